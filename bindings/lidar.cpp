// Bindings of cpp/lidar: RaycastScene, shaped like Open3D's RaycastingScene.
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "pybind_common.h"
#include "raycast_scene.h"
#include "scan_rays.h"

namespace cufund::py_bind {
namespace {

using lidar::RaycastScene;
using lidar::RayHits;
using lidar::RayOrder;
using lidar::SceneResult;
using lidar::SceneStatus;

py::array checked_array(const py::handle& obj, const char* field) {
  py::array arr = py::array::ensure(obj);
  if (!arr) {
    throw py::value_error(std::string(field) + " must be an array, got " +
                          std::string(py::str(py::type::of(obj).attr("__name__"))));
  }
  return arr;
}

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
    case SceneStatus::kIndexOutOfRange: os << " must index existing vertices; triangle " << r.index
                                            << " references a vertex index >= V"; break;
    case SceneStatus::kNonFiniteRay: os << " must be finite, got a NaN or inf in ray " << r.index; break;
    case SceneStatus::kZeroDirection: os << " must have non-zero directions, got (0, 0, 0) in ray " << r.index; break;
    case SceneStatus::kOk: os << ": ok"; break;
  }
  throw py::value_error(os.str());
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

void define_lidar(py::module_& m) {
  m.attr("INVALID_ID") = py::int_(lidar::kInvalidId);
  py::class_<RaycastScene>(m, "RaycastScene", R"doc(
A scene of triangle meshes that casts rays with Embree 3, shaped like Open3D's RaycastingScene.

Add meshes with ``add_triangles``, then ``cast_rays``; the acceleration structure is (re)built on the
first cast after a change. Casting is multithreaded and releases the GIL.
)doc")
      .def(py::init<>())
      .def_property_readonly_static("INVALID_ID", [](py::object) { return lidar::kInvalidId; },
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
        py::array d_arr = checked_array(d_L, "d_L");
        if (d_arr.ndim() != 2 || d_arr.shape(1) != 3) {
          throw py::value_error("d_L must have shape (N, 3), got " + shape_str(d_arr));
        }
        const py::ssize_t n = d_arr.shape(0);
        auto d = as_float64(d_L, "d_L", {n, 3});
        auto tt = as_float64(t, "t", {n});
        py::array k_arr = checked_array(knot_t, "knot_t");
        if (k_arr.ndim() != 1 || k_arr.shape(0) < 2) {
          throw py::value_error("knot_t must have shape (K,) with K >= 2, got " + shape_str(k_arr));
        }
        const py::ssize_t k = k_arr.shape(0);
        auto kt = as_float64(knot_t, "knot_t", {k});
        auto kp = as_float64(knot_p, "knot_p", {k, 3});
        auto kq = as_float64(knot_q, "knot_q", {k, 4});
        for (py::ssize_t i = 0; i + 1 < k; ++i) {
          if (!(kt.data()[i + 1] > kt.data()[i])) throw py::value_error("knot_t must be strictly increasing");
        }
        auto require_finite = [](const double* p, py::ssize_t size, const char* field) {
          for (py::ssize_t i = 0; i < size; ++i) {
            if (!std::isfinite(p[i])) throw py::value_error(std::string(field) + " must be finite, got a NaN or inf");
          }
        };
        require_finite(d.data(), 3 * n, "d_L");
        require_finite(tt.data(), n, "t");
        require_finite(kt.data(), k, "knot_t");
        require_finite(kp.data(), 3 * k, "knot_p");
        require_finite(kq.data(), 4 * k, "knot_q");
        for (py::ssize_t i = 0; i < k; ++i) {
          const double* q = kq.data() + 4 * i;
          if (std::abs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0) > 1e-6) {
            throw py::value_error("knot_q must hold unit quaternions [w, x, y, z], knot " + std::to_string(i) +
                                  " is not");
          }
        }
        for (py::ssize_t i = 0; i < n; ++i) {
          const double* v = d.data() + 3 * i;
          if (v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0) {
            throw py::value_error("d_L must hold non-zero directions, row " + std::to_string(i) + " is zero");
          }
        }
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
}

}  // namespace cufund::py_bind
