// The one header that owns the pybind11 includes and the helpers every binding file shares.
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstddef>
#include <initializer_list>
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

// Converts `obj` to a C-contiguous float64 array of exactly `shape`, accepting real integer and
// floating inputs; anything else raises ValueError naming `field`. (Finiteness is the caller's.)
inline py::array_t<double, py::array::c_style> as_float64(const py::handle& obj, const char* field,
                                                           std::initializer_list<py::ssize_t> shape) {
  py::array arr = py::array::ensure(obj);
  if (!arr) throw py::value_error(std::string(field) + " must be an array of real numbers, got " +
                                  std::string(py::str(py::type::of(obj).attr("__name__"))));
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
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(arr);
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
void define_collision(py::module_& m);  // in dynamics.cpp: Bullet collision checks
void define_esdf(py::module_& m);
void define_odometry(py::module_& m);  // odometry.cpp
void define_planning(py::module_& m);  // bindings/planning.cpp

}  // namespace cufund::py_bind
