// Bindings of cpp/odometry: IMU propagation, deskewing, voxel downsampling and the voxel map used by the
// LiDAR-inertial odometry (python/cufund/estimation). Inputs are validated here; heavy loops drop the GIL.
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>

#include "deskew.h"
#include "imu_propagation.h"
#include "pybind_common.h"
#include "scan_preprocess.h"
#include "thread_pool.h"
#include "voxel_map.h"

namespace cufund::py_bind {
namespace {

using namespace cufund::odometry;

py::array_t<double, py::array::c_style> finite(const py::handle& obj, const char* field,
                                               std::initializer_list<py::ssize_t> shape) {
  auto a = as_float64(obj, field, shape);
  require_finite(a.data(), a.size(), field);
  return a;
}

// (rows, cols) with rows free (-1 in `shape` cannot be expressed by as_float64, so check here).
py::array_t<double, py::array::c_style> finite_rows(const py::handle& obj, const char* field, py::ssize_t cols) {
  py::array arr = checked_array(obj, field);
  const py::ssize_t rows = arr.ndim() >= 1 ? arr.shape(0) : -1;
  if (cols == 0) return finite(obj, field, {rows});
  return finite(obj, field, {rows, cols});
}

Eigen::Vector3d vec3(const py::handle& obj, const char* field) {
  auto a = finite(obj, field, {3});
  return {a.data()[0], a.data()[1], a.data()[2]};
}

Eigen::Matrix3d rotation_from_quat(const py::handle& obj, const char* field) {
  auto a = finite(obj, field, {4});
  const double* q = a.data();
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (std::abs(norm - 1.0) > 1e-6) {
    throw py::value_error(std::string(field) + " must be a unit quaternion [w, x, y, z], got norm " +
                          std::to_string(norm));
  }
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

Eigen::Matrix3d rotation_matrix(const py::handle& obj, const char* field) {
  auto a = finite(obj, field, {3, 3});
  const Eigen::Matrix3d R = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(a.data());
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 || R.determinant() < 0.0) {
    throw py::value_error(std::string(field) + " must be a rotation matrix (orthonormal, det +1)");
  }
  return R;
}

Eigen::Isometry3d rigid_transform(const py::handle& obj, const char* field) {
  auto a = finite(obj, field, {4, 4});
  const Eigen::Matrix4d M = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(a.data());
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 || R.determinant() < 0.0) {
    throw py::value_error(std::string(field) +
                          " must be a rigid transform: its 3x3 block is not a rotation "
                          "(orthonormal, det +1)");
  }
  if (std::abs(M(3, 0)) + std::abs(M(3, 1)) + std::abs(M(3, 2)) + std::abs(M(3, 3) - 1.0) > 1e-12) {
    throw py::value_error(std::string(field) + " must be a 4x4 homogeneous transform with last row [0, 0, 0, 1]");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

py::array_t<double> matrix(std::size_t rows, std::size_t cols) {
  return py::array_t<double>({static_cast<py::ssize_t>(rows), static_cast<py::ssize_t>(cols)});
}

int thread_count(int nthreads) {
  if (nthreads < 0) throw py::value_error("nthreads must be >= 0 (0: all cores), got " + std::to_string(nthreads));
  return nthreads > 0 ? nthreads : ThreadPool::instance().size();
}

// The map with a lock: calls from several Python threads (GIL released) are serialised.
struct PyVoxelMap {
  std::unique_ptr<VoxelMap> map;
  mutable std::mutex m;
};

Robust robust_kind(const std::string& name) {
  if (name == "none") return Robust::kNone;
  if (name == "huber") return Robust::kHuber;
  if (name == "cauchy") return Robust::kCauchy;
  throw py::value_error("robust must be 'none', 'huber' or 'cauchy', got '" + name + "'");
}

py::dict terms_dict(const PlaneTerms& terms, py::ssize_t n) {
  py::array_t<bool> valid(n);
  for (py::ssize_t i = 0; i < n; ++i) valid.mutable_data()[i] = terms.valid[static_cast<std::size_t>(i)] != 0;
  py::array_t<double> normal({n, py::ssize_t{3}});
  if (n) std::memcpy(normal.mutable_data(), terms.normal.data(), terms.normal.size() * sizeof(double));
  const Eigen::Matrix<double, 6, 6, Eigen::RowMajor> H = terms.H;
  py::dict out;
  out["valid"] = valid;
  out["residual"] = py::array_t<double>(n, terms.residual.data());
  out["normal"] = normal;
  out["weight"] = py::array_t<double>(n, terms.weight.data());
  out["H"] = py::array_t<double>({6, 6}, H.data());
  out["b"] = py::array_t<double>(6, terms.b.data());
  out["cost"] = terms.cost;
  out["inliers"] = terms.inliers;
  return out;
}

void positive(double v, const char* field) {
  if (!(std::isfinite(v) && v > 0.0)) throw py::value_error(std::string(field) + " must be a finite number > 0");
}

// The residual half of PlaneParams, validated: what plane_terms and VoxelMap.point_to_plane share.
PlaneParams residual_params(double max_residual, const std::string& robust, double robust_scale, double sigma) {
  positive(max_residual, "max_residual");
  positive(robust_scale, "robust_scale");
  positive(sigma, "sigma");
  PlaneParams prm;
  prm.max_residual = max_residual;
  prm.robust = robust_kind(robust);
  prm.robust_scale = robust_scale;
  prm.sigma = sigma;
  return prm;
}

// deskew's inputs, validated (shared by deskew and prepare_scan).
struct DeskewInputs {
  carray<float> pts;
  py::array_t<double, py::array::c_style> tp, kt, st, rt;
  Eigen::Isometry3d bi, bl;
  py::ssize_t n = 0, k = 0;

  DeskewInputs(const py::handle& points_L, const py::handle& t_points, const py::handle& knot_t,
               const py::handle& states, const py::handle& rates, double t_ref, const py::handle& T_BI,
               const py::handle& T_BL) {
    py::array pa = checked_array(points_L, "points_L");
    const char kind = pa.dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u') {
      throw py::value_error("points_L must have a real numeric dtype, got " + std::string(py::str(pa.dtype())));
    }
    if (pa.ndim() != 2 || pa.shape(1) != 3) {
      throw py::value_error("points_L must have shape (N, 3), got " + shape_str(pa));
    }
    pts = contiguous<float>(pa, "points_L");
    n = pts.shape(0);
    for (py::ssize_t i = 0; i < 3 * n; ++i) {
      if (!std::isfinite(pts.data()[i])) throw py::value_error("points_L must be finite, got a NaN or inf");
    }
    tp = finite(t_points, "t_points", {n});
    kt = finite_rows(knot_t, "knot_t", 0);
    k = kt.shape(0);
    if (k < 2) throw py::value_error("knot_t must hold at least 2 knots");
    for (py::ssize_t i = 1; i < k; ++i) {
      if (!(kt.data()[i] > kt.data()[i - 1])) throw py::value_error("knot_t must be strictly increasing");
    }
    st = finite(states, "states", {k, 10});
    rt = finite(rates, "rates", {k - 1, 6});
    if (!std::isfinite(t_ref)) throw py::value_error("t_ref must be finite [s]");
    bi = rigid_transform(T_BI, "T_BI");
    bl = rigid_transform(T_BL, "T_BL");
  }

  Trajectory trajectory() const { return {kt.data(), st.data(), rt.data(), static_cast<std::size_t>(k)}; }
};

}  // namespace

void define_odometry(py::module_& m) {
  m.def(
      "imu_propagate",
      [](const py::handle& p_W, const py::handle& v_W, const py::handle& q_WI, const py::handle& bias_acc,
         const py::handle& bias_gyr, const py::handle& gravity_W, const py::handle& dt, const py::handle& acc,
         const py::handle& gyr) {
        NavState s;
        s.p_W = vec3(p_W, "p_W");
        s.v_W = vec3(v_W, "v_W");
        s.R_WI = rotation_from_quat(q_WI, "q_WI");
        const Eigen::Vector3d ba = vec3(bias_acc, "bias_acc"), bg = vec3(bias_gyr, "bias_gyr"),
                              g = vec3(gravity_W, "gravity_W");
        auto d = finite_rows(dt, "dt", 0);
        const py::ssize_t n = d.shape(0);
        for (py::ssize_t i = 0; i < n; ++i) {
          if (!(d.data()[i] > 0.0)) throw py::value_error("dt must be > 0 [s] for every sample");
        }
        auto a = finite(acc, "acc", {n, 3});
        auto w = finite(gyr, "gyr", {n, 3});
        auto states = matrix(static_cast<std::size_t>(n) + 1, 10);
        auto rates = matrix(static_cast<std::size_t>(n), 6);
        {
          py::gil_scoped_release release;
          propagate(s, ba, bg, g, d.data(), a.data(), w.data(), static_cast<std::size_t>(n), states.mutable_data(),
                    rates.mutable_data());
        }
        return py::make_tuple(states, rates);
      },
      py::arg("p_W"), py::arg("v_W"), py::arg("q_WI"), py::arg("bias_acc"), py::arg("bias_gyr"), py::arg("gravity_W"),
      py::arg("dt"), py::arg("acc"), py::arg("gyr"),
      "Propagates an IMU-frame state through samples held over dt (n,) [s] with accelerometer acc (n, 3) "
      "[m/s^2] and gyroscope gyr (n, 3) [rad/s] readings, exactly as GTSAM's tangent-space preintegration. "
      "Returns (states (n+1, 10) [p_W, v_W, q_WI (w, x, y, z)], rates (n, 6) [a_W, w_I] held over each sample).");

  m.def(
      "deskew",
      [](const py::handle& points_L, const py::handle& t_points, const py::handle& knot_t, const py::handle& states,
         const py::handle& rates, double t_ref, const py::handle& T_BI, const py::handle& T_BL, int nthreads) {
        const DeskewInputs in(points_L, t_points, knot_t, states, rates, t_ref, T_BI, T_BL);
        const int threads = thread_count(nthreads);
        auto out = matrix(static_cast<std::size_t>(in.n), 3);
        {
          py::gil_scoped_release release;
          deskew(in.pts.data(), in.tp.data(), static_cast<std::size_t>(in.n), in.trajectory(), t_ref, in.bi, in.bl,
                 out.mutable_data(), threads);
        }
        return out;
      },
      py::arg("points_L"), py::arg("t_points"), py::arg("knot_t"), py::arg("states"), py::arg("rates"),
      py::arg("t_ref"), py::arg("T_BI"), py::arg("T_BL"), py::arg("nthreads") = 0,
      "Moves each point of points_L (N, 3), fired at t_points (N,) [s], to the LiDAR frame at t_ref along the IMU "
      "trajectory (knot_t (K,), states (K, 10), rates (K-1, 6) as imu_propagate returns them); T_BI and T_BL are "
      "the 4x4 IMU->body and LiDAR->body extrinsics. Returns (N, 3) float64.");

  m.def(
      "prepare_scan",
      [](const py::handle& points_L, const py::handle& t_points, const py::handle& knot_t, const py::handle& states,
         const py::handle& rates, double t_ref, const py::handle& T_BI, const py::handle& T_BL, double min_range,
         double insert_voxel, double scan_voxel, int nthreads) {
        const DeskewInputs in(points_L, t_points, knot_t, states, rates, t_ref, T_BI, T_BL);
        if (!(std::isfinite(min_range) && min_range >= 0.0)) {
          throw py::value_error("min_range must be a finite number >= 0 [m]");
        }
        positive(insert_voxel, "insert_voxel");
        positive(scan_voxel, "scan_voxel");
        const int threads = thread_count(nthreads);
        PreparedScan out;
        {
          py::gil_scoped_release release;
          out = prepare_scan(in.pts.data(), in.tp.data(), static_cast<std::size_t>(in.n), in.trajectory(), t_ref, in.bi,
                             in.bl, min_range, insert_voxel, scan_voxel, threads);
        }
        auto ins = matrix(out.insert_I.size() / 3, 3), scan = matrix(out.scan_I.size() / 3, 3);
        if (!out.insert_I.empty())
          std::memcpy(ins.mutable_data(), out.insert_I.data(), out.insert_I.size() * sizeof(double));
        if (!out.scan_I.empty())
          std::memcpy(scan.mutable_data(), out.scan_I.data(), out.scan_I.size() * sizeof(double));
        return py::make_tuple(ins, scan);
      },
      py::arg("points_L"), py::arg("t_points"), py::arg("knot_t"), py::arg("states"), py::arg("rates"),
      py::arg("t_ref"), py::arg("T_BI"), py::arg("T_BL"), py::arg("min_range"), py::arg("insert_voxel"),
      py::arg("scan_voxel"), py::arg("nthreads") = 0,
      "A LiDAR frame ready for registration in one call: deskew (same arguments), then points closer than "
      "min_range [m] dropped, voxel_downsample to insert_voxel [m] and that to scan_voxel [m], both in the LiDAR "
      "frame, then moved to the IMU frame. Returns (insert_I (M, 3), scan_I (S, 3)) float64.");

  m.def(
      "voxel_downsample",
      [](const py::handle& points, double voxel) {
        positive(voxel, "voxel");
        auto p = finite_rows(points, "points", 3);
        std::vector<double> out;
        {
          py::gil_scoped_release release;
          out = voxel_downsample(p.data(), static_cast<std::size_t>(p.shape(0)), voxel);
        }
        auto arr = matrix(out.size() / 3, 3);
        if (!out.empty()) std::memcpy(arr.mutable_data(), out.data(), out.size() * sizeof(double));
        return arr;
      },
      py::arg("points"), py::arg("voxel"),
      "The centroid of the points (N, 3) in each occupied cubic voxel of edge `voxel` [m] (grid anchored at the "
      "origin), in the order the voxels are first seen.");

  m.def(
      "plane_terms",
      [](const py::handle& points_I, const py::handle& planes, const py::handle& valid, const py::handle& R_WI,
         const py::handle& p_W, double max_residual, const std::string& robust, double robust_scale, double sigma,
         int nthreads) {
        auto p = finite_rows(points_I, "points_I", 3);
        const py::ssize_t n = p.shape(0);
        auto pl = finite(planes, "planes", {n, 4});
        py::array va = checked_array(valid, "valid");
        if (va.dtype().kind() != 'b' || va.ndim() != 1 || va.shape(0) != n) {
          throw py::value_error("valid must be a bool array of shape (" + std::to_string(n) + ",), got " +
                                std::string(py::str(va.dtype())) + " " + shape_str(va));
        }
        auto v = contiguous<bool>(va, "valid");
        const Eigen::Matrix3d R = rotation_matrix(R_WI, "R_WI");
        const Eigen::Vector3d t = vec3(p_W, "p_W");
        const PlaneParams prm = residual_params(max_residual, robust, robust_scale, sigma);
        const int threads = thread_count(nthreads);
        PlaneTerms terms;
        {
          py::gil_scoped_release release;
          terms = plane_terms(p.data(), pl.data(), reinterpret_cast<const std::uint8_t*>(v.data()),
                              static_cast<std::size_t>(n), R, t, prm, threads);
        }
        return terms_dict(terms, n);
      },
      py::arg("points_I"), py::arg("planes"), py::arg("valid"), py::arg("R_WI"), py::arg("p_W"),
      py::arg("max_residual") = 0.5, py::arg("robust") = "huber", py::arg("robust_scale") = 0.05,
      py::arg("sigma") = 0.02, py::arg("nthreads") = 0,
      "Point-to-plane terms (as VoxelMap.point_to_plane returns them) of points_I (N, 3) placed by (R_WI, p_W) "
      "against fixed planes (N, 4) where valid (N,): the correspondences of VoxelMap.fit_planes kept fixed.");

  py::class_<PyVoxelMap>(m, "VoxelMap", "Incremental hashed voxel map with point-to-plane registration terms.")
      .def(py::init([](double voxel_size, int max_points_per_voxel, double min_point_distance, double max_distance,
                       std::size_t max_voxels) {
             positive(voxel_size, "voxel_size");
             positive(max_distance, "max_distance");
             if (max_points_per_voxel < 1) throw py::value_error("max_points_per_voxel must be >= 1");
             if (!(std::isfinite(min_point_distance) && min_point_distance >= 0.0)) {
               throw py::value_error("min_point_distance must be a finite number >= 0 [m]");
             }
             if (max_voxels < 1) throw py::value_error("max_voxels must be >= 1");
             auto v = std::make_unique<PyVoxelMap>();
             v->map = std::make_unique<VoxelMap>(voxel_size, max_points_per_voxel, min_point_distance, max_distance,
                                                 max_voxels);
             return v;
           }),
           py::arg("voxel_size") = 0.5, py::arg("max_points_per_voxel") = 20, py::arg("min_point_distance") = 0.02,
           py::arg("max_distance") = 100.0, py::arg("max_voxels") = 1000000)
      .def(
          "insert",
          [](PyVoxelMap& self, const py::handle& points_W, const py::handle& origin) {
            auto p = finite_rows(points_W, "points_W", 3);
            const Eigen::Vector3d o = vec3(origin, "origin");
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> lock(self.m);
            return self.map->insert(p.data(), static_cast<std::size_t>(p.shape(0)), o);
          },
          py::arg("points_W"), py::arg("origin"),
          "Adds world points (N, 3) [m], then evicts voxels far from origin (3,). Returns how many were kept.")
      .def(
          "evict",
          [](PyVoxelMap& self, const py::handle& origin) {
            const Eigen::Vector3d o = vec3(origin, "origin");
            std::lock_guard<std::mutex> lock(self.m);
            self.map->evict(o);
          },
          py::arg("origin"))
      .def("clear",
           [](PyVoxelMap& self) {
             std::lock_guard<std::mutex> lock(self.m);
             self.map->clear();
           })
      .def("__len__",
           [](const PyVoxelMap& self) {
             std::lock_guard<std::mutex> lock(self.m);
             return self.map->size();
           })
      .def_property_readonly("voxel_count",
                             [](const PyVoxelMap& self) {
                               std::lock_guard<std::mutex> lock(self.m);
                               return self.map->voxel_count();
                             })
      .def_property_readonly("voxel_size", [](const PyVoxelMap& self) { return self.map->voxel_size(); })
      .def(
          "points",
          [](const PyVoxelMap& self) {
            std::vector<double> out;
            {
              std::lock_guard<std::mutex> lock(self.m);
              out = self.map->points();
            }
            auto arr = matrix(out.size() / 3, 3);
            if (!out.empty()) std::memcpy(arr.mutable_data(), out.data(), out.size() * sizeof(double));
            return arr;
          },
          "Every stored point (M, 3) [m].")
      .def(
          "knn",
          [](const PyVoxelMap& self, const py::handle& queries, int k, double max_distance, int nthreads) {
            if (k < 1 || k > 64) throw py::value_error("k must be in [1, 64], got " + std::to_string(k));
            positive(max_distance, "max_distance");
            auto q = finite_rows(queries, "queries", 3);
            const py::ssize_t n = q.shape(0);
            const int threads = thread_count(nthreads);
            py::array_t<double> nb({n, static_cast<py::ssize_t>(k), py::ssize_t{3}});
            py::array_t<double> d2({n, static_cast<py::ssize_t>(k)});
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(self.m);
              self.map->knn(q.data(), static_cast<std::size_t>(n), k, max_distance, nb.mutable_data(),
                            d2.mutable_data(), threads);
            }
            return py::make_tuple(nb, d2);
          },
          py::arg("queries"), py::arg("k"), py::arg("max_distance"), py::arg("nthreads") = 0,
          "The k nearest stored points within max_distance [m] (capped at the voxel size) of each query (Q, 3): "
          "(neighbours (Q, k, 3), squared distances (Q, k)) ascending; NaN / inf where fewer were found.")
      .def(
          "fit_planes",
          [](const PyVoxelMap& self, const py::handle& points_I, const py::handle& R_WI, const py::handle& p_W,
             int neighbours, double max_neighbour_distance, double max_plane_rms, int nthreads) {
            auto p = finite_rows(points_I, "points_I", 3);
            const Eigen::Matrix3d R = rotation_matrix(R_WI, "R_WI");
            const Eigen::Vector3d t = vec3(p_W, "p_W");
            if (neighbours < 3 || neighbours > 64) throw py::value_error("neighbours must be in [3, 64]");
            positive(max_neighbour_distance, "max_neighbour_distance");
            positive(max_plane_rms, "max_plane_rms");
            PlaneParams prm;
            prm.neighbours = neighbours;
            prm.max_neighbour_distance = max_neighbour_distance;
            prm.max_plane_rms = max_plane_rms;
            const int threads = thread_count(nthreads);
            const py::ssize_t n = p.shape(0);
            py::array_t<bool> valid(n);
            py::array_t<double> planes({n, py::ssize_t{4}});
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(self.m);
              static_assert(sizeof(bool) == sizeof(std::uint8_t), "bool arrays are written as bytes");
              self.map->fit_planes(p.data(), static_cast<std::size_t>(n), R, t, prm,
                                   reinterpret_cast<std::uint8_t*>(valid.mutable_data()), planes.mutable_data(),
                                   threads);
            }
            return py::make_tuple(valid, planes);
          },
          py::arg("points_I"), py::arg("R_WI"), py::arg("p_W"), py::arg("neighbours") = 5,
          py::arg("max_neighbour_distance") = 1.0, py::arg("max_plane_rms") = 0.05, py::arg("nthreads") = 0,
          "Fits a plane to the `neighbours` nearest map points of each of points_I (N, 3) placed by (R_WI, p_W): "
          "(valid (N,), planes (N, 4) [unit normal, offset], normal . x + offset = 0 in the world).")
      .def(
          "point_to_plane",
          [](const PyVoxelMap& self, const py::handle& points_I, const py::handle& R_WI, const py::handle& p_W,
             int neighbours, double max_neighbour_distance, double max_plane_rms, double max_residual,
             const std::string& robust, double robust_scale, double sigma, int nthreads) {
            auto p = finite_rows(points_I, "points_I", 3);
            const Eigen::Matrix3d R = rotation_matrix(R_WI, "R_WI");
            const Eigen::Vector3d t = vec3(p_W, "p_W");
            if (neighbours < 3 || neighbours > 64) throw py::value_error("neighbours must be in [3, 64]");
            positive(max_neighbour_distance, "max_neighbour_distance");
            positive(max_plane_rms, "max_plane_rms");
            PlaneParams prm = residual_params(max_residual, robust, robust_scale, sigma);
            prm.neighbours = neighbours;
            prm.max_neighbour_distance = max_neighbour_distance;
            prm.max_plane_rms = max_plane_rms;
            const int threads = thread_count(nthreads);
            PlaneTerms terms;
            {
              py::gil_scoped_release release;
              std::lock_guard<std::mutex> lock(self.m);
              terms = self.map->point_to_plane(p.data(), static_cast<std::size_t>(p.shape(0)), R, t, prm, threads);
            }
            return terms_dict(terms, p.shape(0));
          },
          py::arg("points_I"), py::arg("R_WI"), py::arg("p_W"), py::arg("neighbours") = 5,
          py::arg("max_neighbour_distance") = 1.0, py::arg("max_plane_rms") = 0.05, py::arg("max_residual") = 0.5,
          py::arg("robust") = "huber", py::arg("robust_scale") = 0.05, py::arg("sigma") = 0.02, py::arg("nthreads") = 0,
          "Point-to-plane terms of points_I (N, 3) seen from the pose (R_WI (3, 3), p_W (3,)): a plane is fitted "
          "to each point's `neighbours` nearest map points. Returns a dict: valid (N,), residual (N,) [m], normal "
          "(N, 3), weight (N,) (robust 'none' | 'huber' | 'cauchy' at robust_scale [m]), H (6, 6) and b (6,) "
          "(sums of w J^T J / sigma^2 and w J^T r / sigma^2 for the right perturbation T_WI Exp(xi), xi = "
          "[rotation, translation]), cost, inliers.");
}

}  // namespace cufund::py_bind
