// cufund._core: one extension, one submodule per C++ area. Users import `cufund`, never this.
#include "pybind_common.h"
#include "thread_pool.h"

namespace cufund::py_bind {
void define_envs(pybind11::module_& m);    // bindings/envs.cpp
void define_render(pybind11::module_& m);  // bindings/render.cpp
}  // namespace cufund::py_bind

PYBIND11_MODULE(_core, m) {
  namespace py = pybind11;
  m.doc() = "cufund's compiled core. Import the public API from `cufund`, not from here.";
  m.attr("__version__") = CUFUND_VERSION;
  m.def(
      "thread_pool_size", [] { return cufund::ThreadPool::instance().size(); },
      "Threads of the shared C++ pool, the caller included (CUFUND_NUM_THREADS, else the CPUs this process may use).");
  py::module_ dynamics = m.def_submodule("dynamics", "Quadrotor rigid-body dynamics (paper §2.1).");
  cufund::py_bind::define_dynamics(dynamics);
  cufund::py_bind::define_collision(dynamics);
  py::module_ control = m.def_submodule("control", "Control allocation and the SE(3) attitude law (paper §2.3).");
  cufund::py_bind::define_control(control);
  py::module_ lidar = m.def_submodule("lidar", "Embree ray casting for LiDAR and depth cameras (paper §2.2).");
  cufund::py_bind::define_lidar(lidar);
  py::module_ perception =
      m.def_submodule("perception", "The tunnel detector's kernels: DBSCAN, line support, deskew-crop.");
  cufund::py_bind::define_perception(perception);
  py::module_ esdf = m.def_submodule("esdf", "Occupancy mapping and exact Euclidean distance fields (paper §2.3).");
  cufund::py_bind::define_esdf(esdf);
  {
    py::module_ odometry = m.def_submodule("odometry", "LiDAR-inertial odometry kernels (issue 12).");
    cufund::py_bind::define_odometry(odometry);
  }
  py::module_ planning =
      m.def_submodule("planning", "Clearance queries and grid path search on the ESDF (paper §2.3).");
  cufund::py_bind::define_planning(planning);
  py::module_ logs = m.def_submodule("logs", "The run log's hot path: packing messages into MCAP blocks (issue 10).");
  cufund::py_bind::define_logs(logs);
  py::module_ envs = m.def_submodule("envs", "Learning environments on the quadrotor batch (issue 28).");
  cufund::py_bind::define_envs(envs);
  py::module_ render = m.def_submodule("render", "Camera images: materials, sun light and shadows (issue 25).");
  cufund::py_bind::define_render(render);
}
