// The one header that owns the pybind11 includes and the helpers every binding file shares.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace cufund::py_bind {

namespace py = pybind11;

// "(10, 3)" for an array's shape.
inline std::string shape_str(const py::array& a) {
  std::ostringstream os;
  os << "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) os << (i ? ", " : "") << a.shape(i);
  os << (a.ndim() == 1 ? ",)" : ")");
  return os.str();
}

inline std::string expected_shape_str(std::initializer_list<py::ssize_t> shape) {
  std::ostringstream os;
  os << "(";
  std::size_t i = 0;
  for (py::ssize_t s : shape) os << (i++ ? ", " : "") << s;
  os << (shape.size() == 1 ? ",)" : ")");
  return os.str();
}

template <typename T>
using carray = py::array_t<T, py::array::c_style | py::array::forcecast>;

inline std::string type_name(const py::handle& obj) { return std::string(py::str(py::type::of(obj).attr("__name__"))); }

// `obj` as a C-contiguous array of T, copied only when needed. Unlike array_t::ensure (which returns
// null and drops the error), a failed allocation raises MemoryError naming `field`, and a failed
// conversion ValueError naming it.
template <typename T>
carray<T> contiguous(const py::handle& obj, const std::string& field) {
  try {
    return carray<T>(py::reinterpret_borrow<py::object>(obj));
  } catch (py::error_already_set& e) {
    if (e.matches(PyExc_MemoryError)) {
      PyErr_SetString(PyExc_MemoryError, ("not enough memory for a contiguous copy of " + field).c_str());
      throw py::error_already_set();
    }
    throw py::value_error(field + " could not be converted to an array: " + std::string(py::str(e.value())));
  }
}

// `obj` as a numpy array of its own dtype (no copy when it already is one), for checking its dtype and shape
// before contiguous<T>(). Unlike array::ensure (which returns null and drops the error), an object numpy cannot
// convert raises ValueError naming `field` and its type, a failed allocation MemoryError.
inline py::array checked_array(const py::handle& obj, const std::string& field) {
  if (py::isinstance<py::array>(obj)) return py::reinterpret_borrow<py::array>(obj);
  try {
    return py::array(py::reinterpret_borrow<py::object>(obj));
  } catch (py::error_already_set& e) {
    if (e.matches(PyExc_MemoryError)) {
      PyErr_SetString(PyExc_MemoryError, ("not enough memory for an array of " + field).c_str());
      throw py::error_already_set();
    }
    throw py::value_error(field + " must be an array, got " + type_name(obj) + " (" + std::string(py::str(e.value())) +
                          ")");
  }
}

// ValueError naming `field` when any of the `size` values at `p` is NaN or infinite.
inline void require_finite(const double* p, py::ssize_t size, const char* field) {
  for (py::ssize_t i = 0; i < size; ++i) {
    if (!std::isfinite(p[i])) throw py::value_error(std::string(field) + " must be finite, got a NaN or inf");
  }
}

// Scalar arguments taken as py::handle and checked here, so a wrong type raises TypeError naming the
// argument (pybind11's own conversion says only "incompatible function arguments").
inline double real_arg(const py::handle& obj, const char* field) {
  if (PyBool_Check(obj.ptr()) || !(PyFloat_Check(obj.ptr()) || PyLong_Check(obj.ptr()) ||
                                   py::isinstance(obj, py::module_::import("numbers").attr("Real")))) {
    throw py::type_error(std::string(field) + " must be a real number, got " + type_name(obj));
  }
  const double x = PyFloat_AsDouble(obj.ptr());
  if (x == -1.0 && PyErr_Occurred()) {
    PyErr_Clear();
    throw py::value_error(std::string(field) + " must be a real number representable as float64, got " +
                          std::string(py::repr(obj)));
  }
  return x;
}

inline double finite_arg(const py::handle& obj, const char* field) {
  const double x = real_arg(obj, field);
  if (!std::isfinite(x)) {
    throw py::value_error(std::string(field) + " must be finite, got " + std::string(py::repr(obj)));
  }
  return x;
}

inline std::int64_t int_arg(const py::handle& obj, const char* field, std::int64_t lo, std::int64_t hi) {
  if (PyBool_Check(obj.ptr()) || !(PyLong_Check(obj.ptr()) || PyIndex_Check(obj.ptr()))) {
    throw py::type_error(std::string(field) + " must be an integer, got " + type_name(obj));
  }
  int overflow = 0;
  py::object idx = py::reinterpret_steal<py::object>(PyNumber_Index(obj.ptr()));
  if (!idx) throw py::error_already_set();
  const long long v = PyLong_AsLongLongAndOverflow(idx.ptr(), &overflow);
  if (overflow != 0 || v < lo || v > hi) {
    throw py::value_error(std::string(field) + " must be an integer in [" + std::to_string(lo) + ", " +
                          std::to_string(hi) + "], got " + std::string(py::repr(obj)));
  }
  return static_cast<std::int64_t>(v);
}

inline int threads_arg(const py::handle& obj) {
  try {
    return static_cast<int>(int_arg(obj, "nthreads", 0, 1 << 20));
  } catch (const py::value_error&) {
    throw py::value_error("nthreads must be >= 0 (0: all cores) and at most 2^20, got " + std::string(py::repr(obj)));
  }
}

inline bool bool_arg(const py::handle& obj, const char* field) {
  if (PyBool_Check(obj.ptr())) return obj.ptr() == Py_True;
  const py::object numpy_bool = py::module_::import("numpy").attr("bool_");
  if (py::isinstance(obj, numpy_bool)) return PyObject_IsTrue(obj.ptr()) == 1;
  throw py::type_error(std::string(field) + " must be True or False, got " + type_name(obj));
}

// Converts `obj` to a C-contiguous float64 array of exactly `shape`, accepting real integer and
// floating inputs; anything else raises ValueError naming `field`. (Finiteness is the caller's.)
inline py::array_t<double, py::array::c_style> as_float64(const py::handle& obj, const char* field,
                                                          std::initializer_list<py::ssize_t> shape) {
  py::array arr = checked_array(obj, field);
  const char kind = arr.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::value_error(std::string(field) + " must have a real numeric dtype (float or int), got " +
                          std::string(py::str(arr.dtype())));
  }
  bool ok = arr.ndim() == static_cast<py::ssize_t>(shape.size());
  std::size_t i = 0;
  for (py::ssize_t s : shape) ok = ok && arr.shape(i++) == s;
  if (!ok) {
    throw py::value_error(std::string(field) + " must have shape " + expected_shape_str(shape) + ", got " +
                          shape_str(arr));
  }
  return contiguous<double>(arr, field);
}

// A writable numpy view of `rows` SoA rows of length n starting at `data`, shaped (n, rows) with
// strides (8, 8n), that keeps `owner` alive. No copy.
inline py::array soa_view(double* data, std::size_t n, int rows, py::handle owner) {
  const auto sz = static_cast<py::ssize_t>(sizeof(double));
  return py::array_t<double>({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(rows)},
                             {sz, sz * static_cast<py::ssize_t>(n)}, data, owner);
}

void define_dynamics(py::module_& m);
void define_control(py::module_& m);
void define_lidar(py::module_& m);
void define_perception(py::module_& m);  // bindings/perception.cpp
void define_collision(py::module_& m);   // in dynamics.cpp: Bullet collision checks
void define_esdf(py::module_& m);
void define_odometry(py::module_& m);  // odometry.cpp
void define_planning(py::module_& m);  // bindings/planning.cpp
void define_logs(py::module_& m);      // bindings/logs.cpp

}  // namespace cufund::py_bind
