// Bindings of cpp/esdf: the exact Euclidean distance transform and the incremental ESDF map.
#include <cmath>
#include <limits>
#include <memory>
#include <shared_mutex>

#include "edt.h"
#include "esdf_map.h"
#include "pybind_common.h"
#include "scan_placement.h"
#include "thread_pool.h"

namespace cufund::py_bind {
namespace {

using Index = std::ptrdiff_t;

// An (N, 3) float64 array named `field`, any N >= 0.
py::array_t<double, py::array::c_style> points_array(const py::handle& obj, const char* field) {
  py::array arr = py::array::ensure(obj);
  const py::ssize_t n = arr && arr.ndim() == 2 ? arr.shape(0) : -1;
  if (n < 0) {
    if (!arr) return as_float64(obj, field, {0, 3});  // raises the "must be an array" error
    throw py::value_error(std::string(field) + " must have shape (N, 3), got " + shape_str(arr));
  }
  try {
    return as_float64(obj, field, {n, 3});
  } catch (const py::value_error&) {
    if (arr.shape(1) != 3) throw py::value_error(std::string(field) + " must have shape (N, 3), got " + shape_str(arr));
    throw;
  }
}

std::array<double, 3> finite3(const py::handle& obj, const char* field) {
  auto a = as_float64(obj, field, {3});
  std::array<double, 3> v{a.at(0), a.at(1), a.at(2)};
  for (double x : v) {
    if (!std::isfinite(x)) {
      std::ostringstream os;
      os << field << " must be finite, got [" << v[0] << ", " << v[1] << ", " << v[2] << "]";
      throw py::value_error(os.str());
    }
  }
  return v;
}

// `occupied` as a C-contiguous uint8 array (nonzero = occupied) of 1 to 3 dimensions.
py::array_t<std::uint8_t, py::array::c_style> occupancy_array(const py::handle& obj) {
  py::array arr = py::array::ensure(obj);
  if (!arr) {
    throw py::value_error("occupied must be a boolean array, got " +
                          std::string(py::str(py::type::of(obj).attr("__name__"))));
  }
  const char kind = arr.dtype().kind();
  if (kind != 'b' && kind != 'i' && kind != 'u') {
    throw py::value_error("occupied must be a boolean (or integer) array, got dtype " +
                          std::string(py::str(arr.dtype())));
  }
  if (arr.ndim() < 1 || arr.ndim() > 3) {
    throw py::value_error("occupied must be a 1-D, 2-D or 3-D array, got shape " + shape_str(arr));
  }
  for (py::ssize_t i = 0; i < arr.ndim(); ++i) {
    if (arr.shape(i) == 0) throw py::value_error("occupied must not be empty, got shape " + shape_str(arr));
  }
  if (kind == 'b' && arr.itemsize() == 1) {
    return contiguous<std::uint8_t>(arr.attr("view")("uint8"), "occupied");
  }
  return contiguous<std::uint8_t>(arr.attr("__ne__")(0).attr("view")("uint8"), "occupied");
}

py::array edt(const py::handle& occupied_obj, const py::handle& voxel_size_obj, bool signed_distance, int nthreads,
              bool single) {
  auto occ = occupancy_array(occupied_obj);
  const py::ssize_t nd = occ.ndim();
  std::array<Index, 3> shape{1, 1, 1};
  for (py::ssize_t i = 0; i < nd; ++i) shape[static_cast<std::size_t>(3 - nd + i)] = occ.shape(i);
  esdf::EdtOptions opt;
  opt.signed_distance = signed_distance;
  opt.nthreads = nthreads;
  py::array vs_arr = py::array::ensure(voxel_size_obj);
  if (vs_arr && vs_arr.ndim() == 0) {
    auto v = as_float64(voxel_size_obj, "voxel_size", std::initializer_list<py::ssize_t>{});
    opt.voxel_size.fill(*v.data());
  } else {
    auto v = as_float64(voxel_size_obj, "voxel_size", {nd});
    for (py::ssize_t i = 0; i < nd; ++i) opt.voxel_size[static_cast<std::size_t>(3 - nd + i)] = v.at(i);
  }
  for (py::ssize_t i = 3 - nd; i < 3; ++i) {
    const double h = opt.voxel_size[static_cast<std::size_t>(i)];
    if (!(std::isfinite(h) && h > 0.0)) {
      std::ostringstream os;
      os << "voxel_size must be finite and > 0 [m] on every axis, got " << h << " on axis " << i - (3 - nd);
      throw py::value_error(os.str());
    }
  }
  std::vector<py::ssize_t> out_shape(occ.shape(), occ.shape() + nd);
  auto run = [&](auto* out) {
    py::gil_scoped_release release;
    return esdf::euclidean_distance_transform(occ.data(), shape, opt, out);
  };
  if (single) {
    py::array_t<float> out(out_shape);
    run(out.mutable_data());
    return out;
  }
  py::array_t<double> out(out_shape);
  run(out.mutable_data());
  return out;
}

py::dict stats_dict(const esdf::EsdfUpdateStats& s) {
  py::dict d;
  d["points"] = s.scan.points;
  d["nan_points"] = s.scan.nan_points;
  d["outside"] = s.scan.outside;
  d["beyond_range"] = s.scan.beyond_range;
  d["beams"] = s.scan.beams;
  d["hit_voxels"] = s.scan.hit_voxels;
  d["free_voxels"] = s.scan.free_voxels;
  d["flipped_voxels"] = s.outside.changed_sites;
  d["changed_distances"] = s.outside.changed_distances + s.inside.changed_distances;
  d["raycast_seconds"] = s.raycast_seconds;
  d["field_seconds"] = s.field_seconds;
  d["lines_recomputed"] = s.outside.columns + s.outside.y_lines + s.outside.x_lines + s.inside.columns +
                          s.inside.y_lines + s.inside.x_lines;
  return d;
}

template <typename T, typename Alloc>
py::array grid_array(const esdf::EsdfMap& m, const std::vector<T, Alloc>& data) {
  const auto& n = m.geometry().shape;
  py::array_t<T> out({n[0], n[1], n[2]});
  std::copy(data.begin(), data.end(), out.mutable_data());
  return out;
}

}  // namespace

void define_esdf(py::module_& m) {
  m.def("edt", &edt, py::arg("occupied"), py::arg("voxel_size"), py::arg("signed"), py::arg("nthreads"),
        py::arg("single"),
        "Exact Euclidean distance transform; use cufund.mapping.edt, which documents the arguments.");

  py::class_<esdf::EsdfMap>(m, "EsdfMap",
                            "Occupancy grid with an incrementally exact ESDF; use cufund.mapping.EsdfMap.")
      .def(py::init([](const py::handle& origin_W, const py::handle& shape_obj, double resolution, float hit,
                       float miss, float lmin, float lmax, float locc, double max_range, bool signed_distance,
                       int nthreads, bool merge_beams) {
             esdf::GridGeometry g;
             g.origin_W = finite3(origin_W, "origin_W");
             auto s = as_float64(shape_obj, "shape", {3});
             for (int i = 0; i < 3; ++i) {
               const double v = s.at(i);
               if (!(v >= 1.0 && v == std::floor(v) && v < 1e6)) {
                 throw py::value_error("shape must be 3 integers >= 1 (voxels along x, y, z), got " +
                                       std::string(py::str(shape_obj)));
               }
               g.shape[static_cast<std::size_t>(i)] = static_cast<Index>(v);
             }
             if (static_cast<double>(g.shape[0]) * static_cast<double>(g.shape[1]) * static_cast<double>(g.shape[2]) >
                 2e9) {
               throw py::value_error("shape must hold at most 2e9 voxels, got " + std::string(py::str(shape_obj)));
             }
             double diagonal2 = 0.0;  // squared distances are kept exactly as int32
             for (int i = 0; i < 3; ++i)
               diagonal2 += std::pow(static_cast<double>(g.shape[static_cast<std::size_t>(i)] - 1), 2);
             if (diagonal2 > esdf::EsdfMap::kMaxSquaredDiagonal) {
               throw py::value_error(
                   "shape must have a diagonal of at most 46340 voxels (squared distances are exact "
                   "32-bit integers), got " +
                   std::string(py::str(shape_obj)));
             }
             if (!(std::isfinite(resolution) && resolution > 0.0)) {
               throw py::value_error("resolution must be finite and > 0 [m], got " + std::to_string(resolution));
             }
             g.resolution = resolution;
             esdf::SensorModel sm;
             sm.log_odds_hit = hit;
             sm.log_odds_miss = miss;
             sm.log_odds_min = lmin;
             sm.log_odds_max = lmax;
             sm.log_odds_occupied = locc;
             sm.max_range = max_range;
             sm.merge_beams = merge_beams;
             esdf::EsdfOptions o;
             o.signed_distance = signed_distance;
             o.nthreads = nthreads;
             py::gil_scoped_release release;
             return std::make_unique<esdf::EsdfMap>(g, sm, o);
           }),
           py::arg("origin_W"), py::arg("shape"), py::arg("resolution"), py::arg("log_odds_hit"),
           py::arg("log_odds_miss"), py::arg("log_odds_min"), py::arg("log_odds_max"), py::arg("log_odds_occupied"),
           py::arg("max_range"), py::arg("signed"), py::arg("nthreads"), py::arg("merge_beams") = false)
      .def(py::init([](const esdf::EsdfMap& other) {
             std::shared_lock<std::shared_mutex> read(other.access_mutex());
             return std::make_unique<esdf::EsdfMap>(other);
           }),
           py::arg("other"), "A deep copy.")
      .def(
          "insert_scan",
          [](esdf::EsdfMap& self, const py::handle& points_W, const py::handle& origin_W) {
            auto p = points_array(points_W, "points_W");
            const auto o = finite3(origin_W, "origin_W");
            esdf::EsdfUpdateStats s;
            {
              py::gil_scoped_release release;
              ForkSafeSection no_fork;
              std::unique_lock<std::shared_mutex> write(self.access_mutex());
              s = self.insert_scan(p.data(), p.shape(0), o.data());
            }
            return stats_dict(s);
          },
          py::arg("points_W"), py::arg("origin_W"))
      .def(
          "insert_scans",
          [](esdf::EsdfMap& self, const py::sequence& scans) {
            std::vector<py::array_t<double, py::array::c_style>> keep;
            std::vector<esdf::EsdfMap::Scan> batch;
            for (std::size_t k = 0; k < scans.size(); ++k) {
              const py::object item = scans[k];
              if (!py::isinstance<py::tuple>(item) || py::len(item) != 2) {
                throw py::value_error("scans[" + std::to_string(k) + "] must be a tuple (points_W, origin_W), got " +
                                      type_name(item));
              }
              const py::tuple pair = item.cast<py::tuple>();
              keep.push_back(points_array(pair[0], "points_W"));
              batch.push_back({keep.back().data(), keep.back().shape(0), finite3(pair[1], "origin_W")});
            }
            esdf::EsdfUpdateStats s;
            {
              py::gil_scoped_release release;
              ForkSafeSection no_fork;
              std::unique_lock<std::shared_mutex> write(self.access_mutex());
              s = self.insert_scans(batch);
            }
            return stats_dict(s);
          },
          py::arg("scans"))
      .def(
          "insert_frames",
          [](esdf::EsdfMap& self, const py::sequence& frames, const py::handle& knots_t, const py::handle& knots_p,
             const py::handle& knots_q, const py::handle& R_BL, const py::handle& t_BL) {
            // Pose knots: (K,) strictly ascending finite stamps, (K, 3) positions, (K, 4) non-zero quaternions.
            py::array kt_arr = py::array::ensure(knots_t);
            const py::ssize_t nk = kt_arr && kt_arr.ndim() == 1 ? kt_arr.shape(0) : -1;
            if (nk < 1)
              throw py::value_error("knots_t must be a non-empty 1-D array of times [s], got " + type_name(knots_t));
            auto kt = as_float64(knots_t, "knots_t", {nk});
            auto kp = as_float64(knots_p, "knots_p", {nk, 3});
            auto kq = as_float64(knots_q, "knots_q", {nk, 4});
            for (py::ssize_t i = 0; i < nk; ++i) {
              const double* q = kq.data() + 4 * i;
              const double* p = kp.data() + 3 * i;
              bool finite = std::isfinite(kt.data()[i]);
              for (int a = 0; a < 3; ++a) finite = finite && std::isfinite(p[a]);
              for (int a = 0; a < 4; ++a) finite = finite && std::isfinite(q[a]);
              if (!finite) throw py::value_error("pose knot " + std::to_string(i) + " must be finite");
              if (!(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] > 1e-18)) {
                throw py::value_error("knots_q row " + std::to_string(i) +
                                      " must be a non-zero quaternion [w, x, y, z]");
              }
              if (i && !(kt.data()[i] > kt.data()[i - 1])) {
                throw py::value_error("knots_t must be strictly ascending, got " + std::to_string(kt.data()[i - 1]) +
                                      " then " + std::to_string(kt.data()[i]) + " at " + std::to_string(i));
              }
            }
            esdf::RigidTransform T_BL;
            auto R = as_float64(R_BL, "R_BL", {3, 3});
            std::copy(R.data(), R.data() + 9, T_BL.R.begin());
            T_BL.t = finite3(t_BL, "t_BL");
            for (double v : T_BL.R) {
              if (!std::isfinite(v)) throw py::value_error("R_BL must be finite");
            }
            // Frames: (points_L (N, 3) [m, LiDAR frame], t (N,) firing times [s], t_origin [s]).
            std::vector<py::array_t<double, py::array::c_style>> points, times;
            std::vector<double> t_origin;
            for (std::size_t k = 0; k < frames.size(); ++k) {
              const py::object item = frames[k];
              if (!py::isinstance<py::tuple>(item) || py::len(item) != 3) {
                throw py::value_error("frames[" + std::to_string(k) +
                                      "] must be a tuple (points_L, t, t_origin), got " + type_name(item));
              }
              const py::tuple f = item.cast<py::tuple>();
              points.push_back(points_array(f[0], "points_L"));
              times.push_back(as_float64(f[1], "t", {points.back().shape(0)}));
              for (py::ssize_t i = 0; i < times.back().shape(0); ++i) {
                if (!std::isfinite(times.back().data()[i])) {
                  throw py::value_error("t must be finite [s], got a NaN or inf at " + std::to_string(i));
                }
              }
              t_origin.push_back(finite_arg(f[2], "t_origin"));
            }
            // Raw views taken with the GIL held; the arrays stay alive in `points` and `times`.
            std::vector<esdf::LidarFrame> views(points.size());
            for (std::size_t k = 0; k < points.size(); ++k) {
              views[k] = {points[k].data(), times[k].data(), points[k].shape(0), t_origin[k]};
            }
            esdf::EsdfUpdateStats s;
            {
              py::gil_scoped_release release;
              ForkSafeSection no_fork;
              const esdf::PoseKnots knots{kt.data(), kp.data(), kq.data(), nk};
              const std::vector<esdf::PlacedFrame> placed =
                  esdf::place_frames(knots, T_BL, views.data(), views.size(), self.options().nthreads);
              std::vector<esdf::EsdfMap::Scan> batch(placed.size());
              for (std::size_t k = 0; k < placed.size(); ++k) {
                batch[k] = {placed[k].points_W.data(), views[k].n, placed[k].origin_W};
              }
              std::unique_lock<std::shared_mutex> write(self.access_mutex());
              s = self.insert_scans(batch);
            }
            return stats_dict(s);
          },
          py::arg("frames"), py::arg("knots_t"), py::arg("knots_p"), py::arg("knots_q"), py::arg("R_BL"),
          py::arg("t_BL"))
      .def(
          "set_occupied",
          [](esdf::EsdfMap& self, py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> index,
             py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast> value) {
            // Shapes and bounds are checked by the Python wrapper; re-check bounds (never write out of range).
            if (index.ndim() != 1 || value.ndim() != 1 || index.shape(0) != value.shape(0)) {
              throw py::value_error("index and value must be 1-D arrays of equal length");
            }
            std::vector<Index> idx(index.data(), index.data() + index.shape(0));
            for (Index i : idx) {
              if (i < 0 || i >= self.occupancy().size()) throw py::value_error("voxel index out of range");
            }
            std::vector<std::uint8_t> val(value.data(), value.data() + value.shape(0));
            esdf::EsdfUpdateStats s;
            {
              py::gil_scoped_release release;
              ForkSafeSection no_fork;
              std::unique_lock<std::shared_mutex> write(self.access_mutex());
              s = self.set_occupied(idx, val);
            }
            return stats_dict(s);
          },
          py::arg("index"), py::arg("value"))
      .def("recompute",
           [](esdf::EsdfMap& self) {
             py::gil_scoped_release release;
             ForkSafeSection no_fork;
             std::unique_lock<std::shared_mutex> write(self.access_mutex());
             self.recompute();
           })
      .def(
          "query",
          [](const esdf::EsdfMap& self, const py::handle& points_W, bool gradient) -> py::object {
            auto p = points_array(points_W, "points_W");
            const py::ssize_t n = p.shape(0);
            for (py::ssize_t i = 0; i < 3 * n; ++i) {
              if (!std::isfinite(p.data()[i])) {
                throw py::value_error("points_W must be finite [m], got a NaN or inf in row " + std::to_string(i / 3));
              }
            }
            py::array_t<double> d(n);
            py::array_t<double> g(gradient ? std::vector<py::ssize_t>{n, 3} : std::vector<py::ssize_t>{0, 3});
            {
              py::gil_scoped_release release;
              ForkSafeSection no_fork;
              std::shared_lock<std::shared_mutex> read(self.access_mutex());
              self.query(p.data(), n, d.mutable_data(), gradient ? g.mutable_data() : nullptr);
            }
            if (gradient) return py::make_tuple(d, g);
            return std::move(d);
          },
          py::arg("points_W"), py::arg("gradient"))
      .def(
          "set_log_odds",
          [](esdf::EsdfMap& self, const py::handle& values) {
            const auto& n = self.geometry().shape;
            py::array arr = py::array::ensure(values);
            if (!arr || arr.ndim() != 3 || arr.shape(0) != n[0] || arr.shape(1) != n[1] || arr.shape(2) != n[2] ||
                arr.dtype().kind() != 'f') {
              throw py::value_error("log_odds must be a float array of shape (" + std::to_string(n[0]) + ", " +
                                    std::to_string(n[1]) + ", " + std::to_string(n[2]) + "), got " +
                                    (arr ? shape_str(arr) : type_name(values)));
            }
            auto v = contiguous<float>(arr, "log_odds");
            const auto& m = self.occupancy().model();
            for (py::ssize_t i = 0; i < v.size(); ++i) {
              const float x = v.data()[i];
              if (!(x >= m.log_odds_min && x <= m.log_odds_max) && x != 0.0f) {
                throw py::value_error("log_odds must lie in [log_odds_min, log_odds_max] (or be 0, unobserved), got " +
                                      std::to_string(x) + " at flat index " + std::to_string(i));
              }
            }
            esdf::EsdfUpdateStats s;
            {
              py::gil_scoped_release release;
              ForkSafeSection no_fork;
              std::unique_lock<std::shared_mutex> write(self.access_mutex());
              s = self.set_log_odds(v.data());
            }
            return stats_dict(s);
          },
          py::arg("log_odds"), "Sets every voxel's log-odds (a saved log_odds()) and updates the field.")
      .def("distances",
           [](const esdf::EsdfMap& self) {
             std::shared_lock<std::shared_mutex> read(self.access_mutex());
             std::vector<double> v(static_cast<std::size_t>(self.occupancy().size()));
             for (Index i = 0; i < self.occupancy().size(); ++i)
               v[static_cast<std::size_t>(i)] = self.voxel_distance(i);
             return grid_array(self, v);
           })
      .def("occupied",
           [](const esdf::EsdfMap& self) {
             std::shared_lock<std::shared_mutex> read(self.access_mutex());
             const auto& n = self.geometry().shape;
             py::array_t<bool> out({n[0], n[1], n[2]});
             bool* o = out.mutable_data();
             for (Index i = 0; i < self.occupancy().size(); ++i) o[i] = self.occupancy().occupied(i);
             return out;
           })
      .def("log_odds",
           [](const esdf::EsdfMap& self) {
             std::shared_lock<std::shared_mutex> read(self.access_mutex());
             return grid_array(self, self.occupancy().log_odds());
           })
      .def("outside_squared",
           [](const esdf::EsdfMap& self) {
             std::shared_lock<std::shared_mutex> read(self.access_mutex());
             return grid_array(self, self.outside_squared());
           })
      .def("inside_squared", [](const esdf::EsdfMap& self) {
        std::shared_lock<std::shared_mutex> read(self.access_mutex());
        return grid_array(self, self.inside_squared());
      });
}

}  // namespace cufund::py_bind
