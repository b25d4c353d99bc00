// Bindings of cpp/planning: certified clearance queries on an ESDF map, triangle voxelisation, and the
// deterministic grid A*. Use cufund.planning (ClearanceQuery, GridPathSearch, voxelize_world).
#include <cmath>
#include <mutex>
#include <shared_mutex>
#include <string>

#include "bspline_optimizer.h"
#include "clearance.h"
#include "esdf_map.h"
#include "grid_astar.h"
#include "min_snap.h"
#include "pybind_common.h"
#include "voxelize.h"

namespace cufund::py_bind {
namespace {

using Index = std::ptrdiff_t;
using planning::Vec3;

Vec3 point3(const py::handle& obj, const char* field) {
  auto a = as_float64(obj, field, {3});
  const Vec3 v{a.at(0), a.at(1), a.at(2)};
  if (!(std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]))) {
    std::ostringstream os;
    os << field << " must be 3 finite numbers [m], got [" << v[0] << ", " << v[1] << ", " << v[2] << "]";
    throw py::value_error(os.str());
  }
  return v;
}

double radius_arg(double r) {
  if (!(std::isfinite(r) && r >= 0.0))
    throw py::value_error("radius must be finite and >= 0 [m], got " + std::to_string(r));
  return r;
}

// The certified-clearance view of an ESDF map (kept alive by the Python object; read under its shared
// lock) or of a static distance array (owned here).
struct ClearanceQuery {
  const esdf::EsdfMap* map = nullptr;
  py::array_t<double, py::array::c_style> distances;
  planning::ClearanceMap view;
  explicit ClearanceQuery(const esdf::EsdfMap& m) : map(&m), view(m) {}
  ClearanceQuery(const esdf::GridGeometry& g, py::array_t<double, py::array::c_style> d)
      : distances(std::move(d)), view(g, distances.data()) {}
  std::shared_lock<std::shared_mutex> read() const {
    return map ? std::shared_lock<std::shared_mutex>(map->access_mutex()) : std::shared_lock<std::shared_mutex>();
  }
};

esdf::GridGeometry geometry_arg(const py::handle& origin_W, const py::handle& shape_obj, double resolution) {
  esdf::GridGeometry g;
  g.origin_W = point3(origin_W, "origin_W");
  auto s = as_float64(shape_obj, "shape", {3});
  for (int i = 0; i < 3; ++i) {
    const double v = s.at(i);
    if (!(v >= 1.0 && v == std::floor(v) && v < 1e6)) {
      throw py::value_error("shape must be 3 integers >= 1, got " + std::string(py::str(shape_obj)));
    }
    g.shape[static_cast<std::size_t>(i)] = static_cast<Index>(v);
  }
  if (static_cast<double>(g.shape[0]) * static_cast<double>(g.shape[1]) * static_cast<double>(g.shape[2]) > 2e9) {
    throw py::value_error("shape must hold at most 2e9 voxels, got " + std::string(py::str(shape_obj)));
  }
  if (!(std::isfinite(resolution) && resolution > 0.0)) {
    throw py::value_error("resolution must be finite and > 0 [m], got " + std::to_string(resolution));
  }
  g.resolution = resolution;
  return g;
}

py::array_t<double> path_array(const std::vector<Vec3>& path) {
  py::array_t<double> out({static_cast<py::ssize_t>(path.size()), py::ssize_t{3}});
  double* o = out.mutable_data();
  for (std::size_t i = 0; i < path.size(); ++i) {
    for (std::size_t a = 0; a < 3; ++a) o[3 * i + a] = path[i][a];
  }
  return out;
}

std::vector<Vec3> path_vector(const py::handle& obj, const char* field) {
  py::array arr = checked_array(obj, field);
  if (arr.ndim() != 2 || arr.shape(1) != 3) {
    throw py::value_error(std::string(field) + " must have shape (K, 3), got " + shape_str(arr));
  }
  auto a = as_float64(obj, field, {arr.shape(0), 3});
  std::vector<Vec3> out(static_cast<std::size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    out[static_cast<std::size_t>(i)] = {a.at(i, 0), a.at(i, 1), a.at(i, 2)};
    for (double x : out[static_cast<std::size_t>(i)]) {
      if (!std::isfinite(x))
        throw py::value_error(std::string(field) + " must be finite, row " + std::to_string(i) + " is not");
    }
  }
  return out;
}

// The scalar fast path (issue 13: a clearance check per OMPL state at about the cost of a builtin call).
// pybind11's dispatcher (overload resolution, argument casters, keyword matching) costs ~200 ns a call,
// ten times the query itself; these are plain METH_FASTCALL builtins bound to a capsule holding the
// query and a reference to its Python object. Keyword calls go to the pybind11 method (same result).
struct ScalarBinding {
  const ClearanceQuery* query;
  PyObject* owner;     // the Python ClearanceQuery (strong reference)
  PyObject* fallback;  // its pybind11 method of the same name (strong reference), for keyword calls
};

void scalar_binding_free(PyObject* capsule) {
  auto* b = static_cast<ScalarBinding*>(PyCapsule_GetPointer(capsule, "cufund.ScalarBinding"));
  if (b == nullptr) return;
  Py_XDECREF(b->fallback);
  Py_XDECREF(b->owner);
  delete b;
}

// False (with a TypeError naming `name`) when `obj` is not a real number.
bool scalar_arg(PyObject* obj, const char* name, double& out) {
  if (PyFloat_CheckExact(obj)) {
    out = PyFloat_AS_DOUBLE(obj);
    return true;
  }
  if (!PyBool_Check(obj) && (PyFloat_Check(obj) || PyLong_Check(obj) || PyNumber_Check(obj))) {
    out = PyFloat_AsDouble(obj);
    if (!(out == -1.0 && PyErr_Occurred())) return true;
    PyErr_Clear();
  }
  PyErr_Format(PyExc_TypeError, "%s must be a real number [m], got %s", name, Py_TYPE(obj)->tp_name);
  return false;
}

PyObject* scalar_fallback(const ScalarBinding* b, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  return PyObject_Vectorcall(b->fallback, args, static_cast<std::size_t>(nargs), kwnames);
}

PyObject* fast_clearance(PyObject* capsule, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  const auto* b = static_cast<const ScalarBinding*>(PyCapsule_GetPointer(capsule, "cufund.ScalarBinding"));
  if (b == nullptr) return nullptr;
  if (kwnames != nullptr || nargs != 3) return scalar_fallback(b, args, nargs, kwnames);
  static const char* names[3] = {"x", "y", "z"};
  Vec3 p;
  for (int i = 0; i < 3; ++i) {
    if (!scalar_arg(args[i], names[i], p[static_cast<std::size_t>(i)])) return nullptr;
  }
  double c;
  {
    const auto lock = b->query->read();
    c = b->query->view.clearance(p);
  }
  return PyFloat_FromDouble(c);
}

PyObject* fast_segment_free(PyObject* capsule, PyObject* const* args, Py_ssize_t nargs, PyObject* kwnames) {
  const auto* b = static_cast<const ScalarBinding*>(PyCapsule_GetPointer(capsule, "cufund.ScalarBinding"));
  if (b == nullptr) return nullptr;
  if (kwnames != nullptr || nargs != 7) return scalar_fallback(b, args, nargs, kwnames);
  static const char* names[7] = {"x0", "y0", "z0", "x1", "y1", "z1", "radius"};
  double v[7];
  for (int i = 0; i < 7; ++i) {
    if (!scalar_arg(args[i], names[i], v[i])) return nullptr;
  }
  if (!(std::isfinite(v[6]) && v[6] >= 0.0)) {
    PyErr_Format(PyExc_ValueError, "radius must be finite and >= 0 [m], got %R", args[6]);
    return nullptr;
  }
  bool free;
  {
    const auto lock = b->query->read();
    free = b->query->view.segment_free({v[0], v[1], v[2]}, {v[3], v[4], v[5]}, v[6]);
  }
  return PyBool_FromLong(free ? 1 : 0);
}

PyMethodDef fast_clearance_def = {
    "clearance", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)(void)>(fast_clearance)),
    METH_FASTCALL | METH_KEYWORDS,
    "clearance(x, y, z) -> float [m]: certified clearance at one point (scalar fast path)."};
PyMethodDef fast_segment_free_def = {
    "segment_free", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)(void)>(fast_segment_free)),
    METH_FASTCALL | METH_KEYWORDS,
    "segment_free(x0, y0, z0, x1, y1, z1, radius) -> bool: certified motion check (scalar fast path)."};

py::object scalar_function(const py::object& self, const char* method, PyMethodDef* def) {
  auto* b = new ScalarBinding{self.cast<const ClearanceQuery*>(), self.ptr(), nullptr};
  py::object fallback = self.attr(method);
  Py_INCREF(self.ptr());
  b->fallback = fallback.release().ptr();
  PyObject* capsule = PyCapsule_New(b, "cufund.ScalarBinding", scalar_binding_free);
  if (capsule == nullptr) {
    Py_DECREF(b->fallback);
    Py_DECREF(b->owner);
    delete b;
    throw py::error_already_set();
  }
  PyObject* f = PyCFunction_NewEx(def, capsule, nullptr);
  Py_DECREF(capsule);
  if (f == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::object>(f);
}

// Waypoint values (K, d), K >= 2, finite, and K - 1 finite segment times > 0 [s].
struct SplineArgs {
  py::array_t<double, py::array::c_style> values, durations;
  std::size_t m = 0, dim = 0;
};

SplineArgs spline_args(const py::handle& values_obj, const py::handle& durations_obj) {
  py::array arr = checked_array(values_obj, "values");
  if (arr.ndim() != 2 || arr.shape(0) < 2 || arr.shape(1) < 1) {
    throw py::value_error("values must have shape (K, d) with K >= 2, got " + shape_str(arr));
  }
  SplineArgs a;
  a.values = as_float64(values_obj, "values", {arr.shape(0), arr.shape(1)});
  a.m = static_cast<std::size_t>(arr.shape(0) - 1);
  a.dim = static_cast<std::size_t>(arr.shape(1));
  for (py::ssize_t i = 0; i < a.values.size(); ++i) {
    if (!std::isfinite(a.values.data()[i])) throw py::value_error("values must be finite");
  }
  a.durations = as_float64(durations_obj, "durations", {arr.shape(0) - 1});
  for (py::ssize_t i = 0; i < a.durations.size(); ++i) {
    const double t = a.durations.data()[i];
    if (!(std::isfinite(t) && t > 0.0)) {
      throw py::value_error("durations must be finite times > 0 [s], got " + std::to_string(t) + " at " +
                            std::to_string(i));
    }
  }
  return a;
}

}  // namespace

void define_planning(py::module_& m) {
  py::class_<ClearanceQuery>(m, "ClearanceQuery",
                             "Certified clearance on an ESDF map; use cufund.planning.ClearanceQuery.")
      .def(py::init<const esdf::EsdfMap&>(), py::arg("esdf_map"), py::keep_alive<1, 2>())
      .def(py::init([](const py::handle& origin_W, double resolution, const py::handle& distances_obj) {
             py::array arr = checked_array(distances_obj, "distances");
             if (arr.ndim() != 3) {
               throw py::value_error("distances must be a 3-D array (nx, ny, nz) [m], got " + shape_str(arr));
             }
             auto d = as_float64(distances_obj, "distances", {arr.shape(0), arr.shape(1), arr.shape(2)});
             const auto g =
                 geometry_arg(origin_W, py::make_tuple(arr.shape(0), arr.shape(1), arr.shape(2)), resolution);
             const double* p = d.data();
             for (py::ssize_t i = 0; i < d.size(); ++i) {
               if (std::isnan(p[i])) throw py::value_error("distances must not hold NaN");
             }
             return std::make_unique<ClearanceQuery>(g, std::move(d));
           }),
           py::arg("origin_W"), py::arg("resolution"), py::arg("distances"))
      .def(
          "clearance",
          [](const ClearanceQuery& self, double x, double y, double z) {
            const auto lock = self.read();
            return self.view.clearance({x, y, z});
          },
          py::arg("x"), py::arg("y"), py::arg("z"))
      .def(
          "clearance_many",
          [](const ClearanceQuery& self, const py::handle& points_W) {
            py::array arr = checked_array(points_W, "points_W");
            if (arr.ndim() != 2 || arr.shape(1) != 3) {
              throw py::value_error("points_W must have shape (N, 3), got " + shape_str(arr));
            }
            auto p = as_float64(points_W, "points_W", {arr.shape(0), 3});
            const py::ssize_t n = p.shape(0);
            py::array_t<double> out(n);
            double* o = out.mutable_data();
            const double* q = p.data();
            {
              py::gil_scoped_release release;
              const auto lock = self.read();
              for (py::ssize_t i = 0; i < n; ++i) o[i] = self.view.clearance({q[3 * i], q[3 * i + 1], q[3 * i + 2]});
            }
            return out;
          },
          py::arg("points_W"))
      .def(
          "segment_free",
          [](const ClearanceQuery& self, double x0, double y0, double z0, double x1, double y1, double z1,
             double radius) {
            radius_arg(radius);
            const auto lock = self.read();
            return self.view.segment_free({x0, y0, z0}, {x1, y1, z1}, radius);
          },
          py::arg("x0"), py::arg("y0"), py::arg("z0"), py::arg("x1"), py::arg("y1"), py::arg("z1"), py::arg("radius"))
      .def(
          "segments_free",
          [](const ClearanceQuery& self, const py::handle& path_obj, double radius) {
            radius_arg(radius);
            const auto path = path_vector(path_obj, "path_W");
            py::array_t<bool> out(static_cast<py::ssize_t>(path.size() > 0 ? path.size() - 1 : 0));
            bool* o = out.mutable_data();
            py::gil_scoped_release release;
            const auto lock = self.read();
            for (std::size_t i = 1; i < path.size(); ++i)
              o[i - 1] = self.view.segment_free(path[i - 1], path[i], radius);
            return out;
          },
          py::arg("path_W"), py::arg("radius"))
      .def(
          "shortcut",
          [](const ClearanceQuery& self, const py::handle& path_obj, double radius) {
            radius_arg(radius);
            const auto path = path_vector(path_obj, "path_W");
            std::vector<Vec3> out;
            {
              py::gil_scoped_release release;
              const auto lock = self.read();
              out = planning::shortcut_path(self.view, path, radius);
            }
            return path_array(out);
          },
          py::arg("path_W"), py::arg("radius"))
      .def(
          "scalar_functions",
          [](const py::object& self) {
            return py::make_tuple(scalar_function(self, "clearance", &fast_clearance_def),
                                  scalar_function(self, "segment_free", &fast_segment_free_def));
          },
          "(clearance(x, y, z), segment_free(x0, y0, z0, x1, y1, z1, radius)) as plain builtins that skip pybind11's "
          "dispatch (each keeps this query alive)")
      .def_property_readonly("min_step", [](const ClearanceQuery& self) { return self.view.min_step(); });

  py::class_<planning::GridAStar>(m, "GridAStar",
                                  "Deterministic A* on the ESDF grid; use cufund.planning.GridPathSearch.")
      .def(py::init<>())
      .def(
          "plan",
          [](planning::GridAStar& self, const ClearanceQuery& query, const py::handle& start, const py::handle& goal,
             double radius, Index max_expansions, bool shortcut, double heuristic_weight, double z_min, double z_max) {
            planning::AStarOptions opt;
            opt.radius = radius_arg(radius);
            if (max_expansions < 1)
              throw py::value_error("max_expansions must be >= 1, got " + std::to_string(max_expansions));
            opt.max_expansions = max_expansions;
            opt.shortcut = shortcut;
            if (!(std::isfinite(heuristic_weight) && heuristic_weight >= 1.0)) {
              throw py::value_error("heuristic_weight must be finite and >= 1, got " +
                                    std::to_string(heuristic_weight));
            }
            opt.heuristic_weight = heuristic_weight;
            if (std::isnan(z_min) || std::isnan(z_max) || !(z_max > z_min)) {
              throw py::value_error("z_max must be > z_min [m], got z_min=" + std::to_string(z_min) +
                                    ", z_max=" + std::to_string(z_max));
            }
            opt.z_min = z_min;
            opt.z_max = z_max;
            const Vec3 s = point3(start, "start_W"), g = point3(goal, "goal_W");
            planning::AStarResult r;
            {
              py::gil_scoped_release release;
              const auto lock = query.read();
              r = self.plan(query.view, s, g, opt);
            }
            py::dict d;
            d["status"] = static_cast<int>(r.status);
            d["path"] = path_array(r.path);
            d["length"] = r.length;
            d["expansions"] = r.expansions;
            d["clearance_queries"] = r.clearance_queries;
            return d;
          },
          py::arg("query"), py::arg("start_W"), py::arg("goal_W"), py::arg("radius"), py::arg("max_expansions"),
          py::arg("shortcut"), py::arg("heuristic_weight"), py::arg("z_min") = -std::numeric_limits<double>::infinity(),
          py::arg("z_max") = std::numeric_limits<double>::infinity());

  m.def(
      "optimize_bspline",
      [](const esdf::EsdfMap& map, const py::handle& start, const py::handle& initial, const py::handle& tail,
         const py::handle& end_target, bool pull_end, double w_smooth, double w_collision, double w_feasibility,
         double w_end, double d_safe, double v_max, double a_max, double dt, int max_iterations) {
        planning::BsplineProblem pb;
        pb.start = path_vector(start, "start");
        pb.tail = path_vector(tail, "tail");
        pb.end_target = point3(end_target, "end_target");
        pb.pull_end = pull_end;
        const auto x0 = path_vector(initial, "initial");
        if (x0.empty()) throw py::value_error("initial must hold at least one control point");
        planning::BsplineWeights w;
        w.smooth = w_smooth;
        w.collision = w_collision;
        w.feasibility = w_feasibility;
        w.end = w_end;
        w.d_safe = d_safe;
        w.v_max = v_max;
        w.a_max = a_max;
        w.dt = dt;
        for (double v : {w_smooth, w_collision, w_feasibility, w_end, v_max, a_max, dt}) {
          if (!(std::isfinite(v) && v > 0.0)) throw py::value_error("weights, limits and dt must be finite and > 0");
        }
        if (!std::isfinite(d_safe)) throw py::value_error("d_safe must be finite");
        planning::LbfgsOptions opt;
        opt.max_iterations = std::max(1, max_iterations);
        planning::BsplineResult r;
        {
          py::gil_scoped_release release;
          std::shared_lock<std::shared_mutex> read(map.access_mutex());
          r = planning::optimize_bspline(map, pb, w, x0, opt);
        }
        py::dict d;
        d["free"] = path_array(r.free);
        d["cost"] = r.cost;
        d["iterations"] = r.iterations;
        d["evaluations"] = r.evaluations;
        return d;
      },
      py::arg("esdf_map"), py::arg("start"), py::arg("initial"), py::arg("tail"), py::arg("end_target"),
      py::arg("pull_end"), py::arg("w_smooth"), py::arg("w_collision"), py::arg("w_feasibility"), py::arg("w_end"),
      py::arg("d_safe"), py::arg("v_max"), py::arg("a_max"), py::arg("dt"), py::arg("max_iterations"));

  m.def(
      "voxelize_triangles",
      [](const py::handle& origin_W, const py::handle& shape_obj, double resolution, const py::handle& vertices_obj,
         const py::handle& triangles_obj) {
        const esdf::GridGeometry g = geometry_arg(origin_W, shape_obj, resolution);
        py::array varr = checked_array(vertices_obj, "vertices");
        if (varr.ndim() != 2 || varr.shape(1) != 3) {
          throw py::value_error("vertices must have shape (V, 3), got " + shape_str(varr));
        }
        auto v = as_float64(vertices_obj, "vertices", {varr.shape(0), 3});
        for (py::ssize_t i = 0; i < v.size(); ++i) {
          if (!std::isfinite(v.data()[i])) throw py::value_error("vertices must be finite");
        }
        py::array tarr = checked_array(triangles_obj, "triangles");
        if (tarr.dtype().kind() != 'i' && tarr.dtype().kind() != 'u') {
          throw py::value_error("triangles must have an integer dtype, got " + std::string(py::str(tarr.dtype())));
        }
        if (tarr.ndim() != 2 || tarr.shape(1) != 3) {
          throw py::value_error("triangles must have shape (T, 3), got " + shape_str(tarr));
        }
        auto t = contiguous<std::int64_t>(tarr, "triangles");
        for (py::ssize_t i = 0; i < t.size(); ++i) {
          if (t.data()[i] < 0 || t.data()[i] >= v.shape(0)) {
            throw py::value_error("triangles must index vertices (0 <= index < " + std::to_string(v.shape(0)) +
                                  "), got " + std::to_string(t.data()[i]));
          }
        }
        std::vector<Index> idx;
        {
          py::gil_scoped_release release;
          idx = planning::voxelize_triangles(g, v.data(), v.shape(0), t.data(), t.shape(0));
        }
        py::array_t<std::int64_t> out(static_cast<py::ssize_t>(idx.size()));
        std::copy(idx.begin(), idx.end(), out.mutable_data());
        return out;
      },
      py::arg("origin_W"), py::arg("shape"), py::arg("resolution"), py::arg("vertices"), py::arg("triangles"));

  m.def(
      "min_derivative_spline",
      [](const py::handle& values, const py::handle& durations, int order) {
        if (order < 1 || order > 8) throw py::value_error("order must be 1..8, got " + std::to_string(order));
        const SplineArgs a = spline_args(values, durations);
        std::vector<double> c;
        {
          py::gil_scoped_release release;
          c = planning::min_derivative_spline(a.values.data(), a.m, a.dim, a.durations.data(), order);
        }
        py::array_t<double> out(
            {static_cast<py::ssize_t>(a.m), static_cast<py::ssize_t>(2 * order), static_cast<py::ssize_t>(a.dim)});
        std::copy(c.begin(), c.end(), out.mutable_data());
        return out;
      },
      py::arg("values"), py::arg("durations"), py::arg("order"),
      "Coefficients (M, 2 order, d) of the minimum-derivative spline through values (M + 1, d) with durations (M,).");
  m.def(
      "snap_cost_and_gradient",
      [](const py::handle& values, const py::handle& durations) {
        const SplineArgs a = spline_args(values, durations);
        py::array_t<double> grad(static_cast<py::ssize_t>(a.m));
        double J;
        {
          double* g = grad.mutable_data();
          py::gil_scoped_release release;
          J = planning::snap_cost_and_gradient(a.values.data(), a.m, a.dim, a.durations.data(), g);
        }
        return py::make_tuple(J, grad);
      },
      py::arg("values"), py::arg("durations"), "(snap cost J, dJ/dT (M,)) of the minimum-snap spline.");
  m.def(
      "optimize_segment_times",
      [](const py::handle& values, const py::handle& durations, int max_iterations, double gtol) {
        const SplineArgs a = spline_args(values, durations);
        if (max_iterations < 0)
          throw py::value_error("max_iterations must be >= 0, got " + std::to_string(max_iterations));
        if (!(std::isfinite(gtol) && gtol >= 0.0))
          throw py::value_error("gtol must be finite and >= 0, got " + std::to_string(gtol));
        planning::TimeOptimizationResult r;
        {
          py::gil_scoped_release release;
          r = planning::optimize_segment_times(a.values.data(), a.m, a.dim, a.durations.data(), max_iterations, gtol);
        }
        py::array_t<double> T(static_cast<py::ssize_t>(a.m));
        std::copy(r.durations.begin(), r.durations.end(), T.mutable_data());
        py::dict d;
        d["durations"] = T;
        d["iterations"] = r.iterations;
        d["evaluations"] = r.evaluations;
        return d;
      },
      py::arg("values"), py::arg("durations"), py::arg("max_iterations"), py::arg("gtol"),
      "Snap-optimal segment times with the same total (BFGS on log T); a dict of durations, iterations, evaluations.");
}

}  // namespace cufund::py_bind
