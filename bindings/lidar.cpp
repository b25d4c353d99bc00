// Bindings of cpp/lidar: RaycastScene, shaped like Open3D's RaycastingScene.
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "batch_cast.h"
#include "lidar_frame.h"
#include "pybind_common.h"
#include "range_model_args.h"
#include "raycast_scene.h"
#include "scan_pattern.h"
#include "scan_rays.h"

namespace cufund::py_bind {
namespace {

using lidar::RaycastScene;
using lidar::RayHits;
using lidar::RayOrder;
using lidar::SceneResult;
using lidar::SceneStatus;

// (N, 3) real -> C-contiguous float32.
py::array_t<float, py::array::c_style> vertices_array(const py::handle& obj) {
  py::array arr = checked_array(obj, "vertices");
  const char kind = arr.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::value_error("vertices must have a real numeric dtype, got " + std::string(py::str(arr.dtype())));
  }
  if (arr.ndim() != 2 || arr.shape(1) != 3) {
    throw py::value_error("vertices must have shape (V, 3), got " + shape_str(arr));
  }
  return contiguous<float>(arr, "vertices");
}

// (T, 3) integer, non-negative -> C-contiguous uint32.
py::array_t<std::uint32_t, py::array::c_style> triangles_array(const py::handle& obj) {
  py::array arr = checked_array(obj, "triangles");
  const char kind = arr.dtype().kind();
  if (kind != 'i' && kind != 'u') {
    throw py::value_error("triangles must have an integer dtype, got " + std::string(py::str(arr.dtype())));
  }
  if (arr.ndim() != 2 || arr.shape(1) != 3) {
    throw py::value_error("triangles must have shape (T, 3), got " + shape_str(arr));
  }
  // Range-check in 64 bits before narrowing to uint32 (a forcecast would wrap 2^32 + k to k).
  auto check = [](const auto* p, py::ssize_t size) {
    for (py::ssize_t i = 0; i < size; ++i) {
      const bool negative = p[i] < 0;
      if (negative || static_cast<std::uint64_t>(p[i]) > std::numeric_limits<std::uint32_t>::max() - 1) {
        throw py::value_error("triangles must hold vertex indices in [0, V), got " + std::to_string(p[i]) +
                              " in triangle " + std::to_string(i / 3));
      }
    }
  };
  if (kind == 'i') {
    auto i64 = contiguous<std::int64_t>(arr, "triangles");
    check(i64.data(), i64.size());
  } else {
    auto u64 = contiguous<std::uint64_t>(arr, "triangles");
    check(u64.data(), u64.size());
  }
  return contiguous<std::uint32_t>(arr, "triangles");
}

[[noreturn]] void raise_status(const SceneResult& r, const char* field) {
  std::ostringstream os;
  os << field;
  switch (r.status) {
    case SceneStatus::kNoTriangles: os << " must hold at least one triangle, got (0, 3)"; break;
    case SceneStatus::kNonFiniteVertex: os << " must be finite, got a NaN or inf in vertex " << r.index; break;
    case SceneStatus::kIndexOutOfRange:
      os << " must index existing vertices; triangle " << r.index << " references a vertex index >= V";
      break;
    case SceneStatus::kNonFiniteRay: os << " must be finite, got a NaN or inf in ray " << r.index; break;
    case SceneStatus::kZeroDirection: os << " must have non-zero directions, got (0, 0, 0) in ray " << r.index; break;
    case SceneStatus::kInstanced: os << " cannot be added: another RaycastScene instances this one"; break;
    case SceneStatus::kOk: os << ": ok"; break;
  }
  throw py::value_error(os.str());
}

// Pose knots of a moving sensor, checked: K >= 2 strictly increasing finite times, finite positions,
// unit quaternions.
struct Knots {
  py::array_t<double, py::array::c_style> t, p, q;
};

Knots knots_args(const py::handle& knot_t, const py::handle& knot_p, const py::handle& knot_q) {
  py::array k_arr = checked_array(knot_t, "knot_t");
  if (k_arr.ndim() != 1 || k_arr.shape(0) < 2) {
    throw py::value_error("knot_t must have shape (K,) with K >= 2, got " + shape_str(k_arr));
  }
  const py::ssize_t k = k_arr.shape(0);
  Knots out{as_float64(knot_t, "knot_t", {k}), as_float64(knot_p, "knot_p", {k, 3}),
            as_float64(knot_q, "knot_q", {k, 4})};
  const double* kt = out.t.data();
  for (py::ssize_t i = 0; i + 1 < k; ++i) {
    if (!(kt[i + 1] > kt[i])) throw py::value_error("knot_t must be strictly increasing");
  }
  require_finite(kt, k, "knot_t");
  require_finite(out.p.data(), 3 * k, "knot_p");
  require_finite(out.q.data(), 4 * k, "knot_q");
  for (py::ssize_t i = 0; i < k; ++i) {
    const double* q = out.q.data() + 4 * i;
    if (std::abs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0) > 1e-6) {
      throw py::value_error("knot_q must hold unit quaternions [w, x, y, z], knot " + std::to_string(i) + " is not");
    }
  }
  return out;
}

// d_L (N, 3) float64 with no zero row.
py::array_t<double, py::array::c_style> directions_arg(const py::handle& d_L) {
  py::array d_arr = checked_array(d_L, "d_L");
  if (d_arr.ndim() != 2 || d_arr.shape(1) != 3) {
    throw py::value_error("d_L must have shape (N, 3), got " + shape_str(d_arr));
  }
  const py::ssize_t n = d_arr.shape(0);
  auto d = as_float64(d_L, "d_L", {n, 3});
  require_finite(d.data(), 3 * n, "d_L");
  for (py::ssize_t i = 0; i < n; ++i) {
    const double* v = d.data() + 3 * i;
    if (v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0) {
      throw py::value_error("d_L must hold non-zero directions, row " + std::to_string(i) + " is zero");
    }
  }
  return d;
}

// An optional (n,) float64 array (None: an empty array; test the argument for None, not the array).
py::array_t<double, py::array::c_style> optional_rows(const py::handle& obj, const char* field, py::ssize_t n) {
  if (obj.is_none()) return {};
  auto a = as_float64(obj, field, {n});
  require_finite(a.data(), n, field);
  return a;
}

// The optional realism terms of the range model (RangeModel past n_reflectivity), with their draw arrays.
struct RealismArgs {
  py::handle noise_z, noise_std, noise_per_m, incidence_noise, detect_draw, max_range_at_10pct, detection_softness,
      mixed_draw, mixed_probability, mixed_edge, dt_noise, dt_max, intensity_z, intensity_noise;
};

// Reads the realism terms into `model`; the arrays it returns keep the draws alive.
std::vector<py::array_t<double, py::array::c_style>> realism_args(const RealismArgs& a, py::ssize_t n,
                                                                  lidar::RangeModel& model) {
  std::vector<py::array_t<double, py::array::c_style>> keep;
  auto rows = [&](const py::handle& obj, const char* field, bool pairs) -> const double* {
    if (obj.is_none()) return nullptr;
    auto arr = pairs ? as_float64(obj, field, {n, 2}) : as_float64(obj, field, {n});
    require_finite(arr.data(), arr.size(), field);
    keep.push_back(arr);
    return keep.back().data();
  };
  model.noise_z = rows(a.noise_z, "noise_z", false);
  model.noise_std = nonnegative_arg(a.noise_std, "range_noise_std");
  model.noise_per_m = nonnegative_arg(a.noise_per_m, "range_noise_per_m");
  model.incidence_noise = nonnegative_arg(a.incidence_noise, "incidence_noise");
  model.detect_draw = rows(a.detect_draw, "detect_draw", false);
  model.max_range_at_10pct = nonnegative_arg(a.max_range_at_10pct, "max_range_at_10pct", true);
  if (!(model.max_range_at_10pct > 0.0)) {
    throw py::value_error("max_range_at_10pct must be > 0 [m] (inf: no range limit), got " +
                          std::string(py::repr(a.max_range_at_10pct)));
  }
  model.detection_softness = nonnegative_arg(a.detection_softness, "detection_softness");
  model.mixed_draw = rows(a.mixed_draw, "mixed_draw", true);
  model.mixed_probability = nonnegative_arg(a.mixed_probability, "mixed_pixel_probability");
  if (model.mixed_probability > 1.0) {
    throw py::value_error("mixed_pixel_probability must be in [0, 1], got " +
                          std::string(py::repr(a.mixed_probability)));
  }
  model.mixed_edge = nonnegative_arg(a.mixed_edge, "mixed_pixel_edge_m");
  model.dt_noise = rows(a.dt_noise, "dt_noise", false);
  model.dt_max = nonnegative_arg(a.dt_max, "dt_max", true);
  model.intensity_z = rows(a.intensity_z, "intensity_z", false);
  model.intensity_noise = nonnegative_arg(a.intensity_noise, "intensity_noise");
  return keep;
}

py::dict scan_frame(const RaycastScene& scene, const py::handle& d_L, const py::handle& t, const py::handle& channel,
                    const py::handle& t0_obj, const py::handle& knot_t, const py::handle& knot_p,
                    const py::handle& knot_q, const py::handle& range_min_obj, const py::handle& range_max_obj,
                    const py::handle& noise_obj, const py::handle& keep_obj, const py::handle& dropout_obj,
                    const py::handle& refl_obj, const py::handle& nthreads_obj, const RealismArgs& realism) {
  const int nthreads = threads_arg(nthreads_obj);
  auto d = directions_arg(d_L);
  const py::ssize_t n = d.shape(0);
  if (n >= (py::ssize_t{1} << 32) - 1) throw py::value_error("d_L must hold fewer than 2^32 - 1 rays");
  auto tt = as_float64(t, "t", {n});
  require_finite(tt.data(), n, "t");
  py::array ch_arr = checked_array(channel, "channel");
  if (ch_arr.dtype().kind() != 'i' && ch_arr.dtype().kind() != 'u') {
    throw py::value_error("channel must have an integer dtype, got " + std::string(py::str(ch_arr.dtype())));
  }
  if (ch_arr.ndim() != 1 || ch_arr.shape(0) != n) {
    throw py::value_error("channel must have shape (" + std::to_string(n) + ",), got " + shape_str(ch_arr));
  }
  auto ch = contiguous<std::int32_t>(ch_arr, "channel");
  const double t0 = finite_arg(t0_obj, "t0");
  const Knots kn = knots_args(knot_t, knot_p, knot_q);
  lidar::RangeModel model;
  model.range_min = finite_arg(range_min_obj, "range_min");
  model.range_max = finite_arg(range_max_obj, "range_max");
  model.dropout = finite_arg(dropout_obj, "dropout");
  auto noise = optional_rows(noise_obj, "noise", n);
  auto keep = optional_rows(keep_obj, "keep_draw", n);
  model.noise = noise_obj.is_none() ? nullptr : noise.data();
  model.keep_draw = keep_obj.is_none() ? nullptr : keep.data();
  const auto realism_draws = realism_args(realism, n, model);
  if (model.noise && model.noise_z) throw py::value_error("noise and noise_z must not both be given");
  py::array_t<double, py::array::c_style> refl;
  if (!refl_obj.is_none()) {
    py::array r_arr = checked_array(refl_obj, "reflectivity");
    if (r_arr.ndim() != 1) throw py::value_error("reflectivity must have shape (G,), got " + shape_str(r_arr));
    refl = as_float64(refl_obj, "reflectivity", {r_arr.shape(0)});
    model.reflectivity = refl.data();
    model.n_reflectivity = static_cast<std::size_t>(refl.shape(0));
  }
  const lidar::FrameRays rays{d.data(), tt.data(), ch.data(), static_cast<std::size_t>(n)};
  const lidar::FrameKnots knots{kn.t.data(), kn.p.data(), kn.q.data(), static_cast<std::size_t>(kn.t.shape(0))};
  thread_local lidar::CastFrame cast;
  {
    py::gil_scoped_release release;
    lidar::cast_frame(scene, rays, t0, knots, model, nthreads, cast);
  }
  if (cast.bad_geometry != lidar::kInvalidId) {
    throw py::value_error("reflectivity must have one entry per geometry, got " + std::to_string(model.n_reflectivity) +
                          " and a hit on geometry " + std::to_string(cast.bad_geometry));
  }
  const auto m = static_cast<py::ssize_t>(cast.returns.size());
  py::array_t<double> dt(m), ranges(m);
  py::array_t<float> points_L({m, py::ssize_t{3}}), points_W({m, py::ssize_t{3}});
  py::array_t<std::int32_t> channels(m);
  py::array_t<std::uint32_t> ids(m);
  py::array intensity = model.reflectivity ? py::array(py::array_t<double>(m)) : py::array(py::array_t<float>(m));
  lidar::FrameReturns out{dt.mutable_data(),
                          points_L.mutable_data(),
                          ranges.mutable_data(),
                          model.reflectivity ? static_cast<double*>(intensity.mutable_data()) : nullptr,
                          model.reflectivity ? nullptr : static_cast<float*>(intensity.mutable_data()),
                          channels.mutable_data(),
                          points_W.mutable_data(),
                          ids.mutable_data()};
  {
    py::gil_scoped_release release;
    lidar::write_returns(rays, model, cast, out);
  }
  py::dict r;
  r["dt"] = dt;
  r["points_L"] = points_L;
  r["ranges"] = ranges;
  r["intensity"] = intensity;
  r["channel"] = channels;
  r["points_W"] = points_W;
  r["object_ids"] = ids;
  return r;
}

py::dict cast(const RaycastScene& scene, const py::handle& rays_obj, const py::handle& nthreads_obj,
              const py::object& coherent) {
  const int nthreads = threads_arg(nthreads_obj);
  py::array arr = checked_array(rays_obj, "rays");
  const char kind = arr.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::value_error("rays must have a real numeric dtype (float32 preferred), got " +
                          std::string(py::str(arr.dtype())));
  }
  if (arr.ndim() < 1 || arr.shape(arr.ndim() - 1) != 6) {
    throw py::value_error("rays must have shape (N, 6), got " + shape_str(arr));
  }
  auto rays = contiguous<float>(arr, "rays");
  std::vector<py::ssize_t> lead(arr.shape(), arr.shape() + arr.ndim() - 1);
  const auto n = static_cast<std::size_t>(rays.size() / 6);
  RayOrder order = RayOrder::kAuto;
  if (!coherent.is_none()) order = bool_arg(coherent, "coherent") ? RayOrder::kCoherent : RayOrder::kIncoherent;

  auto with = [&](py::ssize_t k) {
    std::vector<py::ssize_t> s = lead;
    if (k > 0) s.push_back(k);
    return s;
  };
  py::array_t<float> t_hit(with(0));
  py::array_t<std::uint32_t> geometry_ids(with(0)), primitive_ids(with(0));
  py::array_t<float> uvs(with(2)), normals(with(3));
  RayHits out{t_hit.mutable_data(), geometry_ids.mutable_data(), primitive_ids.mutable_data(), uvs.mutable_data(),
              normals.mutable_data()};
  SceneResult r;
  {
    py::gil_scoped_release release;
    r = scene.cast_rays(rays.data(), n, out, nthreads, order);
  }
  if (r.status != SceneStatus::kOk) raise_status(r, "rays");
  py::dict d;
  d["t_hit"] = t_hit;
  d["geometry_ids"] = geometry_ids;
  d["primitive_ids"] = primitive_ids;
  d["primitive_uvs"] = uvs;
  d["primitive_normals"] = normals;
  d["normals"] = normals;
  return d;
}

}  // namespace

void define_lidar_batch(py::module_& m);

void define_lidar(py::module_& m) {
  m.attr("INVALID_ID") = py::int_(lidar::kInvalidId);
  py::class_<RaycastScene>(m, "RaycastScene", R"doc(
A scene of triangle meshes that casts rays with Embree 3, shaped like Open3D's RaycastingScene.

Add meshes with ``add_triangles``, then ``cast_rays``; the acceleration structure is (re)built on the
first cast after a change. Casting is multithreaded and releases the GIL.
)doc")
      .def(py::init<>())
      .def(py::init([](const RaycastScene& base) {
             return std::make_unique<RaycastScene>(RaycastScene::Instancing{}, base);
           }),
           py::arg("base"), py::keep_alive<1, 2>(),
           "A scene starting with base's geometries as one instance (shared, not copied): a hit on base's geometry g "
           "reports id g, meshes added here take the ids after base's. base can no longer change (its add_triangles "
           "raises ValueError).")
      .def_property_readonly_static(
          "INVALID_ID", [](py::object) { return lidar::kInvalidId; },
          "geometry_ids / primitive_ids of a ray that hit nothing (4294967295).")
      .def(
          "add_triangles",
          [](RaycastScene& self, const py::handle& vertices, const py::handle& triangles) {
            auto v = vertices_array(vertices);
            auto t = triangles_array(triangles);
            const SceneResult r = self.add_triangles(v.data(), static_cast<std::size_t>(v.shape(0)), t.data(),
                                                     static_cast<std::size_t>(t.shape(0)));
            if (r.status == SceneStatus::kNonFiniteVertex) raise_status(r, "vertices");
            if (r.status != SceneStatus::kOk) raise_status(r, "triangles");
            return r.id;
          },
          py::arg("vertices"), py::arg("triangles"), R"doc(
Adds a mesh and returns its geometry id (0, 1, 2, ... in order of addition).

vertices: (V, 3) real [m]; triangles: (T, 3) integer vertex indices, T >= 1. The mesh is copied.
Degenerate (zero-area) triangles are kept but never hit.
)doc")
      .def(
          "cast_rays",
          [](const RaycastScene& self, const py::handle& rays, const py::handle& nthreads, const py::object& coherent) {
            return cast(self, rays, nthreads, coherent);
          },
          py::arg("rays"), py::arg("nthreads") = 0, py::arg("coherent") = py::none(), R"doc(
Casts rays and returns the first hit of each.

rays: (..., 6) rows of (origin xyz, direction xyz), float32 preferred (others are converted); every
value finite and every direction non-zero, else ValueError naming the ray.
nthreads: 0 uses every core. coherent: None guesses from the rays (8-wide packets when consecutive
rays share an origin, regrouped into compact angular tiles on large scenes; otherwise, for 4096 rays
or more on scenes of 1000 triangles or more, rays sorted by where they head and cast in packets in
that order), True forces packets of consecutive rays, False single rays in the given order. The
results are the same either way (bit for bit, except the last bits of distances, barycentrics and
normals with True).

Returns a dict of arrays shaped like the leading dims of ``rays``:
``t_hit`` float32 (inf on a miss; in units of the direction's length), ``geometry_ids`` and
``primitive_ids`` uint32 (INVALID_ID on a miss), ``primitive_uvs`` float32 (..., 2) barycentrics,
``primitive_normals`` float32 (..., 3) unit geometric normals (zero on a miss), also as ``normals``.
)doc")
      .def_property_readonly("num_geometries", &RaycastScene::num_geometries)
      .def_property_readonly("num_triangles", &RaycastScene::num_triangles);

  m.def(
      "scan_rays",
      [](const py::handle& d_L, const py::handle& t, const py::handle& knot_t, const py::handle& knot_p,
         const py::handle& knot_q) {
        auto d = directions_arg(d_L);
        const py::ssize_t n = d.shape(0);
        auto tt = as_float64(t, "t", {n});
        require_finite(tt.data(), n, "t");
        const Knots kn = knots_args(knot_t, knot_p, knot_q);
        const py::ssize_t k = kn.t.shape(0);
        const auto& kt = kn.t;
        const auto& kp = kn.p;
        const auto& kq = kn.q;
        py::array_t<float> rays({n, py::ssize_t{6}});
        {
          py::gil_scoped_release release;
          lidar::scan_rays(d.data(), tt.data(), static_cast<std::size_t>(n), kt.data(), kp.data(), kq.data(),
                           static_cast<std::size_t>(k), rays.mutable_data());
        }
        return rays;
      },
      py::arg("d_L"), py::arg("t"), py::arg("knot_t"), py::arg("knot_p"), py::arg("knot_q"), R"doc(
(N, 6) float32 rays of a moving sensor: ray i leaves from the sensor pose at time t[i], interpolated
between pose knots (knot_t (K,) increasing [s], knot_p (K, 3) p_WL [m], knot_q (K, 4) q_WL [w, x, y, z]
unit, consecutive signs aligned) linearly in position and by slerp in rotation, along R_WL d_L[i].
)doc");

  m.def(
      "scan_frame",
      [](const RaycastScene& scene, const py::handle& d_L, const py::handle& t, const py::handle& channel,
         const py::handle& t0, const py::handle& knot_t, const py::handle& knot_p, const py::handle& knot_q,
         const py::handle& range_min, const py::handle& range_max, const py::handle& noise, const py::handle& keep_draw,
         const py::handle& dropout, const py::handle& reflectivity, const py::handle& nthreads,
         const py::handle& noise_z, const py::handle& range_noise_std, const py::handle& range_noise_per_m,
         const py::handle& incidence_noise, const py::handle& detect_draw, const py::handle& max_range_at_10pct,
         const py::handle& detection_softness, const py::handle& mixed_draw, const py::handle& mixed_pixel_probability,
         const py::handle& mixed_pixel_edge_m, const py::handle& dt_noise, const py::handle& dt_max,
         const py::handle& intensity_z, const py::handle& intensity_noise) {
        const RealismArgs realism{noise_z,
                                  range_noise_std,
                                  range_noise_per_m,
                                  incidence_noise,
                                  detect_draw,
                                  max_range_at_10pct,
                                  detection_softness,
                                  mixed_draw,
                                  mixed_pixel_probability,
                                  mixed_pixel_edge_m,
                                  dt_noise,
                                  dt_max,
                                  intensity_z,
                                  intensity_noise};
        return scan_frame(scene, d_L, t, channel, t0, knot_t, knot_p, knot_q, range_min, range_max, noise, keep_draw,
                          dropout, reflectivity, nthreads, realism);
      },
      py::arg("scene"), py::arg("d_L"), py::arg("t"), py::arg("channel"), py::arg("t0"), py::arg("knot_t"),
      py::arg("knot_p"), py::arg("knot_q"), py::arg("range_min"), py::arg("range_max"), py::arg("noise") = py::none(),
      py::arg("keep_draw") = py::none(), py::arg("dropout") = 0.0, py::arg("reflectivity") = py::none(),
      py::arg("nthreads") = 0, py::kw_only(), py::arg("noise_z") = py::none(), py::arg("range_noise_std") = 0.0,
      py::arg("range_noise_per_m") = 0.0, py::arg("incidence_noise") = 0.0, py::arg("detect_draw") = py::none(),
      py::arg("max_range_at_10pct") = std::numeric_limits<double>::infinity(), py::arg("detection_softness") = 0.1,
      py::arg("mixed_draw") = py::none(), py::arg("mixed_pixel_probability") = 0.0, py::arg("mixed_pixel_edge_m") = 0.3,
      py::arg("dt_noise") = py::none(), py::arg("dt_max") = std::numeric_limits<double>::infinity(),
      py::arg("intensity_z") = py::none(), py::arg("intensity_noise") = 0.0, R"doc(
One LiDAR frame in one call: the rays of scan_rays (ray i at time t0 + t[i] [s]) cast into ``scene`` (in
coherent packets, channel by channel: the hits of single rays, up to the last bits of distances, which
Embree does not promise), and the returns the sensor reports.
A ray returns when its true range is in [range_min, range_max] [m] and, with ``keep_draw`` (N,), when
keep_draw[i] >= dropout; its measured range is max(true + noise[i], 0) with ``noise`` (N,) [m] (None: none).
Intensity: reflectivity[geometry id] x |cos incidence| clipped to [0, 1], float64 (None: |cos incidence|,
float32). Returns a dict over the returns, in ray order: ``dt`` (M,) t[i], ``points_L`` (M, 3) float32,
``ranges`` (M,), ``intensity`` (M,), ``channel`` (M,) int32, ``points_W`` (M, 3) float32 noise-free world
hits and ``object_ids`` (M,) uint32.
The realism terms (keyword-only, each off while its draws are None; cufund.sensors.LidarParams documents them):
``noise_z`` (N,) unit normals: the range noise is noise_z[i] x sigma, sigma = (range_noise_std +
range_noise_per_m r) (1 + incidence_noise (1 / cos theta - 1)), theta the incidence angle capped at 85 deg
(not with ``noise``); ``detect_draw`` (N,) uniforms: a return is lost unless detect_draw[i] < its detection
probability, 1 up to r_max = max_range_at_10pct sqrt(reflectivity cos theta / 0.1) and 0 past r_max (1 +
detection_softness), a smoothstep between; ``mixed_draw`` (N, 2) uniforms: a return next to a depth edge of its
channel (a neighbouring ray's true range more than mixed_pixel_edge_m away) lands at r + mixed_draw[i, 1]
(r_neighbour - r) when mixed_draw[i, 0] < mixed_pixel_probability; ``dt_noise`` (N,) [s] added to the reported
dt, clamped to [0, dt_max]; ``intensity_z`` (N,) unit normals: intensity x (1 + s intensity_z[i]), s =
intensity_noise (1 + (r / r_max)^2) with a finite max_range_at_10pct, else intensity_noise.
)doc");

  m.def(
      "mid360_frame",
      [](const py::handle& k_obj, const py::handle& n_obj, const py::handle& point_rate, const py::handle& lasers,
         const py::handle& spin_rate, const py::handle& sweep_ratio, const py::handle& elevation_min,
         const py::handle& elevation_max, const py::handle& nthreads_obj) {
        const int nthreads = threads_arg(nthreads_obj);
        const std::int64_t k = int_arg(k_obj, "k", 0, std::int64_t{1} << 40);
        const std::int64_t n = int_arg(n_obj, "n", 0, std::int64_t{1} << 31);
        lidar::Mid360Params p{finite_arg(point_rate, "point_rate"),       int_arg(lasers, "lasers", 1, 1 << 20),
                              finite_arg(spin_rate, "spin_rate"),         finite_arg(sweep_ratio, "sweep_ratio"),
                              finite_arg(elevation_min, "elevation_min"), finite_arg(elevation_max, "elevation_max")};
        if (!(p.point_rate > 0)) throw py::value_error("point_rate must be > 0 [1/s]");
        if (static_cast<double>(k + 1) * static_cast<double>(n) >= 9007199254740992.0) {  // 2^53: exact firing indices
          throw py::value_error("k * n must stay below 2^53 (the frame's ray indices as exact float64), got k = " +
                                std::to_string(k) + ", n = " + std::to_string(n));
        }
        py::array_t<double> t(n), az(n), el(n), d({static_cast<py::ssize_t>(n), py::ssize_t{3}});
        py::array_t<std::int32_t> ch(n);
        {
          py::gil_scoped_release release;
          lidar::mid360_frame(p, k, static_cast<std::size_t>(n), t.mutable_data(), az.mutable_data(), el.mutable_data(),
                              ch.mutable_data(), d.mutable_data(), nthreads);
        }
        return py::make_tuple(t, az, el, ch, d);
      },
      py::arg("k"), py::arg("n"), py::arg("point_rate"), py::arg("lasers"), py::arg("spin_rate"),
      py::arg("sweep_ratio"), py::arg("elevation_min"), py::arg("elevation_max"), py::arg("nthreads") = 0, R"doc(
Frame k (n rays) of cufund.sensors.patterns.Mid360Pattern: (t [s] from the frame start, azimuth [rad],
elevation [rad], channel int32, unit directions d_L (n, 3)). Ray i fires at (k n + i) / point_rate, laser
i % lasers; azimuth 2 pi (spin_rate t + channel / lasers) mod 2 pi, elevation the middle of
[elevation_min, elevation_max] plus half its width times sin(2 pi spin_rate sweep_ratio t + pi channel / lasers).
)doc");
  define_lidar_batch(m);  // after RaycastScene, which its signatures name
}

// Batched casts (batch_cast.h): one sensor per vehicle, every vehicle in one call.
namespace {

py::array_t<float, py::array::c_style> batch_directions(const py::handle& obj) {
  py::array arr = checked_array(obj, "d_S");
  const char kind = arr.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::value_error("d_S must have a real numeric dtype (float32 preferred), got " +
                          std::string(py::str(arr.dtype())));
  }
  if (arr.ndim() != 2 || arr.shape(1) != 3) throw py::value_error("d_S must have shape (R, 3), got " + shape_str(arr));
  return contiguous<float>(arr, "d_S");
}

py::ssize_t rows_of(const py::handle& obj, const char* field, py::ssize_t cols) {
  py::array arr = checked_array(obj, field);
  if (arr.ndim() != 2 || arr.shape(1) != cols) {
    throw py::value_error(std::string(field) + " must have shape (N, " + std::to_string(cols) + "), got " +
                          shape_str(arr));
  }
  return arr.shape(0);
}

void raise_batch(const lidar::BatchResult& r) {
  const std::string i = std::to_string(r.index);
  switch (r.status) {
    case lidar::BatchStatus::kOk: return;
    case lidar::BatchStatus::kNonFinitePose:
      throw py::value_error("p_WS and q_WS must be finite, sensor " + i + " is not");
    case lidar::BatchStatus::kZeroQuaternion:
      throw py::value_error("q_WS must hold non-zero quaternions [w, x, y, z], sensor " + i + " is zero");
    case lidar::BatchStatus::kNonFiniteDirection:
      throw py::value_error("d_S must be finite, direction " + i + " is not");
    case lidar::BatchStatus::kZeroDirection:
      throw py::value_error("d_S must hold non-zero directions, direction " + i + " is zero");
    case lidar::BatchStatus::kBadBox:
      throw py::value_error("box " + i +
                            ": box_p_W and box_q_W must be finite (q non-zero) and box_half_extents finite and >= 0");
    case lidar::BatchStatus::kBadOwner:
      throw py::value_error("box_owner must hold box indices in [-1, M), sensor " + i + "'s is not");
  }
}

}  // namespace

void define_lidar_batch(py::module_& m) {
  m.def(
      "batch_rays",
      [](const py::handle& d_S_obj, const py::handle& p_obj, const py::handle& q_obj, const py::handle& nthreads_obj) {
        const int nthreads = threads_arg(nthreads_obj);
        auto d = batch_directions(d_S_obj);
        const py::ssize_t n = rows_of(p_obj, "p_WS", 3);
        auto p = as_float64(p_obj, "p_WS", {n, 3});
        auto q = as_float64(q_obj, "q_WS", {n, 4});
        const py::ssize_t r = d.shape(0);
        py::array_t<float> rays({n, r, py::ssize_t{6}});
        lidar::BatchResult res;
        {
          py::gil_scoped_release release;
          res = lidar::batch_rays({p.data(), q.data(), static_cast<std::size_t>(n)}, d.data(),
                                  static_cast<std::size_t>(r), rays.mutable_data(), nthreads);
        }
        raise_batch(res);
        return rays;
      },
      py::arg("d_S"), py::arg("p_WS"), py::arg("q_WS"), py::arg("nthreads") = 0, R"doc(
The (N, R, 6) float32 rays batch_cast casts: ray (i, r) leaves p_WS[i] along R(q_WS[i]) d_S[r].

d_S: (R, 3) sensor-frame directions (float32); p_WS (N, 3) [m]; q_WS (N, 4) [w, x, y, z] (normalised here).
)doc");

  m.def(
      "batch_cast",
      [](const RaycastScene& scene, const py::handle& d_S_obj, const py::handle& p_obj, const py::handle& q_obj,
         const py::handle& box_p, const py::handle& box_q, const py::handle& box_h, const py::handle& box_owner,
         const py::handle& range_min, const py::handle& range_max, const py::handle& miss_value,
         const py::handle& noise_std, const py::handle& noise_per_m, const py::handle& dropout, const py::handle& seed,
         const py::handle& frame, const py::handle& nthreads_obj) {
        const int nthreads = threads_arg(nthreads_obj);
        auto d = batch_directions(d_S_obj);
        const py::ssize_t n = rows_of(p_obj, "p_WS", 3);
        auto p = as_float64(p_obj, "p_WS", {n, 3});
        auto q = as_float64(q_obj, "q_WS", {n, 4});
        const py::ssize_t r = d.shape(0);
        lidar::VehicleBoxes boxes;
        py::array_t<double, py::array::c_style> bp, bq, bh;
        py::array_t<std::int64_t, py::array::c_style> owner;
        if (!box_p.is_none()) {
          const py::ssize_t m_boxes = rows_of(box_p, "box_p_W", 3);
          bp = as_float64(box_p, "box_p_W", {m_boxes, 3});
          if (box_q.is_none() || box_h.is_none()) {
            throw py::value_error("box_q_W and box_half_extents are required with box_p_W");
          }
          bq = as_float64(box_q, "box_q_W", {m_boxes, 4});
          bh = as_float64(box_h, "box_half_extents", {m_boxes, 3});
          boxes = {bp.data(), bq.data(), bh.data(), static_cast<std::size_t>(m_boxes), nullptr};
          if (!box_owner.is_none()) {
            py::array oa = checked_array(box_owner, "box_owner");
            if (oa.dtype().kind() != 'i' && oa.dtype().kind() != 'u') {
              throw py::value_error("box_owner must have an integer dtype, got " + std::string(py::str(oa.dtype())));
            }
            if (oa.ndim() != 1 || oa.shape(0) != n) {
              throw py::value_error("box_owner must have shape (" + std::to_string(n) + ",), got " + shape_str(oa));
            }
            owner = contiguous<std::int64_t>(oa, "box_owner");
            boxes.owner = owner.data();
          }
        }
        const lidar::BatchRangeModel model =
            batch_range_model_arg({range_min, range_max, miss_value, noise_std, noise_per_m, dropout, seed, frame});
        py::array_t<float> out({n, r});
        lidar::BatchResult res;
        {
          py::gil_scoped_release release;
          res = lidar::batch_cast(scene, {p.data(), q.data(), static_cast<std::size_t>(n)}, d.data(),
                                  static_cast<std::size_t>(r), boxes, model, out.mutable_data(), nthreads);
        }
        raise_batch(res);
        return out;
      },
      py::arg("scene"), py::arg("d_S"), py::arg("p_WS"), py::arg("q_WS"), py::kw_only(),
      py::arg("box_p_W") = py::none(), py::arg("box_q_W") = py::none(), py::arg("box_half_extents") = py::none(),
      py::arg("box_owner") = py::none(), py::arg("range_min") = 0.0,
      py::arg("range_max") = std::numeric_limits<double>::infinity(),
      py::arg("miss_value") = std::numeric_limits<double>::infinity(), py::arg("noise_std") = 0.0,
      py::arg("noise_per_m") = 0.0, py::arg("dropout") = 0.0, py::arg("seed") = 0, py::arg("frame") = 0,
      py::arg("nthreads") = 0, R"doc(
One sensor on each of N vehicles cast in one call (GIL released, threads over vehicles): (N, R) float32.

The rays of batch_rays(d_S, p_WS, q_WS) are cast into ``scene``, each vehicle's in the 8-wide coherent
packets of ``scene.cast_rays(rays[i], coherent=True)`` (bit for bit its t_hit), and into the vehicles'
oriented boxes (box_p_W (M, 3) [m], box_q_W (M, 4) [w, x, y, z], box_half_extents (M, 3) [m]; sensor i does
not see box box_owner[i], -1: none). A value is the distance along the ray's direction in units of its length
(a range for unit d_S, the depth along the optical axis for pinhole directions (1, -x_n, -y_n)); outside
[range_min, range_max] or a miss: miss_value. Noise (off by default): a valid return becomes
max(t + (noise_std + noise_per_m t) z, 0), z standard normal, and is lost (miss_value) with probability
``dropout``; vehicle i's draws in frame ``frame`` come from a stream keyed by (seed + i, frame), so vehicle i
of a batch seeded s draws what a batch of one seeded s + i does.
)doc");
}

}  // namespace cufund::py_bind
