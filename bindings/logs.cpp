// cufund._core.logs: the run log's hot path. A RecordPacker appends one message's fixed-size CDR fields to a
// topic's block buffer (McapLogger.write calls it for every message of a run). It is binding-only: what it does
// is read a Python message's attributes and copy its arrays' bytes, so there is no C++ library under cpp/ for it.
#include <pybind11/numpy.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "pybind_common.h"

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "records are packed in the host's order: little-endian");

namespace cufund::py_bind {
namespace {

// One array field of the record: its attribute, its dtype (numpy's singleton for a native type: compared by
// identity, as the Python path did) and its size in bytes.
struct ArrayField {
  py::object name;
  py::object dtype;
  py::ssize_t nbytes;
  py::ssize_t elements;
};

// One scalar field: 'd' float64, 'q' int64, '?' bool (struct's codes, little-endian as the host).
struct ScalarField {
  py::object name;
  char code;
};

class RecordPacker {
 public:
  RecordPacker(const std::vector<std::string>& scalar_names, const std::string& scalar_codes,
               const std::vector<std::string>& array_names, const std::vector<py::object>& array_dtypes,
               const std::vector<py::ssize_t>& array_nbytes, const std::vector<std::string>& absent_names,
               py::object slow)
      : slow_(std::move(slow)) {
    if (scalar_names.size() != scalar_codes.size()) throw py::value_error("scalar_codes: one code per scalar name");
    if (array_names.size() != array_dtypes.size() || array_names.size() != array_nbytes.size()) {
      throw py::value_error("array_dtypes, array_nbytes: one per array name");
    }
    if (!PyCallable_Check(slow_.ptr())) throw py::type_error("slow must be callable");
    record_bytes_ = 24;
    for (std::size_t i = 0; i < scalar_names.size(); ++i) {
      const char c = scalar_codes[i];
      if (c != 'd' && c != 'q' && c != '?') throw py::value_error("scalar_codes: each 'd', 'q' or '?'");
      scalars_.push_back({py::str(scalar_names[i]), c});
      record_bytes_ += c == '?' ? 1 : 8;
    }
    const py::object dtype_type = py::module_::import("numpy").attr("dtype");
    for (std::size_t i = 0; i < array_names.size(); ++i) {
      if (!py::isinstance(array_dtypes[i], dtype_type)) throw py::type_error("array_dtypes: numpy dtypes");
      const py::ssize_t itemsize = py::dtype::from_args(array_dtypes[i]).itemsize();
      if (array_nbytes[i] <= 0 || array_nbytes[i] % itemsize != 0) {
        throw py::value_error("array_nbytes: each > 0 and a multiple of its dtype's itemsize");
      }
      arrays_.push_back({py::str(array_names[i]), array_dtypes[i], array_nbytes[i], array_nbytes[i] / itemsize});
      record_bytes_ += array_nbytes[i];
    }
    for (const auto& n : absent_names) absent_.push_back(py::str(n));
  }

  // Appends `message` (or hands it to `slow(index, log, publish, sequence, message)` when a field does not
  // match the topic's layout); returns the messages added since the last drain.
  std::int64_t add(py::handle message, py::handle log, py::handle publish, py::handle sequence) {
    const std::int64_t index = count_++;
    const std::size_t start = buffer_.size();
    if (!(put_time(log) && put_time(publish) && put_time(sequence) && pack(message))) {
      buffer_.resize(start);
      PyErr_Clear();
      slow_(index, log, publish, sequence, message);
    }
    return count_;
  }

  // The packed records and their number; empties the buffer.
  py::tuple drain() {
    py::bytes out(reinterpret_cast<const char*>(buffer_.data()), buffer_.size());
    const std::int64_t n = count_;
    buffer_.clear();
    count_ = 0;
    return py::make_tuple(out, n);
  }

  py::ssize_t record_bytes() const { return record_bytes_; }
  std::int64_t count() const { return count_; }

 private:
  template <typename T>
  void put(const T& v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    buffer_.insert(buffer_.end(), p, p + sizeof(T));
  }

  // A time or sequence number: a Python int in [0, 2^64) (anything else takes the checked path, which names it).
  bool put_time(py::handle v) {
    if (!PyLong_CheckExact(v.ptr())) return false;
    const unsigned long long x = PyLong_AsUnsignedLongLong(v.ptr());
    if (x == static_cast<unsigned long long>(-1) && PyErr_Occurred()) return false;
    put(static_cast<std::uint64_t>(x));
    return true;
  }

  bool pack(py::handle message) {
    for (const auto& s : scalars_) {
      PyObject* v = PyObject_GetAttr(message.ptr(), s.name.ptr());
      if (v == nullptr) return false;
      bool ok = true;
      if (s.code == 'd') {
        const double x = PyFloat_AsDouble(v);  // floats, ints and anything with __float__, as struct's 'd'
        ok = !(x == -1.0 && PyErr_Occurred());
        put(x);
      } else if (s.code == 'q') {
        long long x = 0;
        ok = PyIndex_Check(v) != 0;  // struct's 'q' takes what has __index__ (ints, bools, numpy integers)
        if (ok) {
          PyObject* i = PyNumber_Index(v);
          ok = i != nullptr;
          if (ok) {
            x = PyLong_AsLongLong(i);
            ok = !(x == -1 && PyErr_Occurred());
            Py_DECREF(i);
          }
        }
        put(static_cast<std::int64_t>(x));
      } else {
        const int b = PyObject_IsTrue(v);
        ok = b >= 0;
        put(static_cast<std::uint8_t>(b == 1));
      }
      Py_DECREF(v);
      if (!ok) return false;
    }
    auto& api = py::detail::npy_api::get();
    for (const auto& a : arrays_) {
      PyObject* v = PyObject_GetAttr(message.ptr(), a.name.ptr());
      if (v == nullptr) return false;
      bool ok = api.PyArray_Check_(v) != 0;
      if (ok) {
        const auto* arr = py::detail::array_proxy(v);
        ok = arr->descr == a.dtype.ptr() && (arr->flags & py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_) != 0;
        if (ok) {
          py::ssize_t n = 1;
          for (int d = 0; d < arr->nd; ++d) n *= arr->dimensions[d];
          ok = n == a.elements;  // the dtype is the layout's, so equal counts mean equal bytes
          if (ok) {
            const auto* p = reinterpret_cast<const std::uint8_t*>(arr->data);
            buffer_.insert(buffer_.end(), p, p + a.nbytes);
          }
        }
      }
      Py_DECREF(v);
      if (!ok) return false;
    }
    for (const auto& name : absent_) {
      PyObject* v = PyObject_GetAttr(message.ptr(), name.ptr());
      if (v == nullptr) return false;
      const bool ok = v == Py_None;
      Py_DECREF(v);
      if (!ok) return false;
    }
    return true;
  }

  std::vector<ScalarField> scalars_;
  std::vector<ArrayField> arrays_;
  std::vector<py::object> absent_;
  py::object slow_;
  std::vector<std::uint8_t> buffer_;
  std::int64_t count_ = 0;
  py::ssize_t record_bytes_ = 0;
};

// `add` as a plain METH_FASTCALL builtin bound to a capsule holding the packer and a strong reference to its
// Python object: pybind11's dispatcher (overload resolution, argument casters) would cost more than the packing.
struct AddBinding {
  RecordPacker* packer;
  PyObject* owner;
};

void add_binding_free(PyObject* capsule) {
  auto* b = static_cast<AddBinding*>(PyCapsule_GetPointer(capsule, "cufund.RecordPackerAdd"));
  if (b == nullptr) return;
  Py_XDECREF(b->owner);
  delete b;
}

PyObject* fast_add(PyObject* capsule, PyObject* const* args, Py_ssize_t nargs) {
  if (nargs != 4) {
    PyErr_Format(PyExc_TypeError, "add(message, log, publish, sequence) takes 4 arguments, got %zd", nargs);
    return nullptr;
  }
  auto* b = static_cast<AddBinding*>(PyCapsule_GetPointer(capsule, "cufund.RecordPackerAdd"));
  if (b == nullptr) return nullptr;
  try {
    return PyLong_FromLongLong(b->packer->add(args[0], args[1], args[2], args[3]));
  } catch (py::error_already_set& e) {
    e.restore();
    return nullptr;
  } catch (const std::exception& e) {
    PyErr_SetString(PyExc_RuntimeError, e.what());
    return nullptr;
  }
}

PyMethodDef fast_add_def = {"add", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)(void)>(fast_add)),
                            METH_FASTCALL, "add(message, log, publish, sequence) -> messages since the last drain."};

py::object fast_adder(py::object self) {
  auto* b = new AddBinding{self.cast<RecordPacker*>(), self.ptr()};
  Py_INCREF(self.ptr());
  PyObject* capsule = PyCapsule_New(b, "cufund.RecordPackerAdd", add_binding_free);
  if (capsule == nullptr) {
    Py_DECREF(b->owner);
    delete b;
    throw py::error_already_set();
  }
  PyObject* f = PyCFunction_NewEx(&fast_add_def, capsule, nullptr);
  Py_DECREF(capsule);
  if (f == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::object>(f);
}

}  // namespace

void define_logs(py::module_& m) {
  py::class_<RecordPacker>(m, "RecordPacker",
                           "Appends messages of one fixed layout to a byte buffer of packed records: log, publish "
                           "and sequence (uint64), the scalars, then the arrays' bytes (little-endian host).")
      .def(py::init<const std::vector<std::string>&, const std::string&, const std::vector<std::string>&,
                    const std::vector<py::object>&, const std::vector<py::ssize_t>&, const std::vector<std::string>&,
                    py::object>(),
           py::arg("scalar_names"), py::arg("scalar_codes"), py::arg("array_names"), py::arg("array_dtypes"),
           py::arg("array_nbytes"), py::arg("absent_names"), py::arg("slow"))
      .def("add", &RecordPacker::add, py::arg("message"), py::arg("log"), py::arg("publish"), py::arg("sequence"),
           "Packs the message, or calls slow(index, log, publish, sequence, message) when it does not fit the "
           "layout; returns the messages added since the last drain.")
      .def_property_readonly("fast_add", &fast_adder,
                             "add as a plain builtin (no pybind11 dispatch): what the logger calls per message.")
      .def("drain", &RecordPacker::drain, "(bytes of the packed records, their number); empties the buffer.")
      .def_property_readonly("record_bytes", &RecordPacker::record_bytes)
      .def_property_readonly("count", &RecordPacker::count);
}

}  // namespace cufund::py_bind
