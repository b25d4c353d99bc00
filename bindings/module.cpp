// cufund._core: one extension, one submodule per C++ area. Users import `cufund`, never this.
#include "pybind_common.h"

PYBIND11_MODULE(_core, m) {
  namespace py = pybind11;
  m.doc() = "cufund's compiled core. Import the public API from `cufund`, not from here.";
  m.attr("__version__") = CUFUND_VERSION;
  py::module_ dynamics = m.def_submodule("dynamics", "Quadrotor rigid-body dynamics (paper §2.1).");
  cufund::py_bind::define_dynamics(dynamics);
  py::module_ esdf = m.def_submodule("esdf", "Occupancy mapping and exact Euclidean distance fields (paper §2.3).");
  cufund::py_bind::define_esdf(esdf);
}
