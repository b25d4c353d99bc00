// cufund._core.logs: the run log's hot path. A LogCore takes every message a run publishes
// (McapLogger.write is its `write`, a plain METH_FASTCALL builtin: one C call per message, no Python frame),
// copies a fixed-size message's fields straight into its topic's block of CDR rows, and hands a full block to a
// cufund::logs::ChunkWriter, whose thread encodes the MCAP records (the rows, their Foxglove views, the message
// indexes), compresses and writes them without the GIL. Anything else goes to a Python callable.
#include <pybind11/numpy.h>
#include <structmember.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include "mcap_chunk_writer.h"
#include "pybind_common.h"

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "CDR rows are little-endian, as this host");

namespace cufund::py_bind {
namespace {

using logs::Block;
using logs::ChunkWriter;
using logs::ViewSpec;

// A scalar field: 'd' float64, 'q' int64, '?' bool (struct's codes), at `offset` in the CDR row.
struct ScalarField {
  py::object name;
  char code;
  std::size_t offset;
  Py_ssize_t slot;  // where a slotted class keeps the attribute in its instances, or -1 (then getattr)
};

// An array field: its attribute, dtype (numpy's singleton for a native type: compared by identity), elements,
// bytes and offset in the row.
struct ArrayField {
  py::object name;
  py::object dtype;
  py::ssize_t elements;
  std::size_t nbytes, offset;
  Py_ssize_t slot;
};

// The offset of attribute `name` in instances of `cls` when it is a plain __slots__ member (a member descriptor
// of an object slot on the class), else -1. The packer reads such a field straight from the instance of that
// exact class (cufund's messages are slotted dataclasses); anything else goes through getattr.
Py_ssize_t slot_offset(const py::object& cls, const py::object& name) {
  if (!PyType_Check(cls.ptr())) return -1;
  PyObject* d = _PyType_Lookup(reinterpret_cast<PyTypeObject*>(cls.ptr()), name.ptr());  // borrowed
  if (d == nullptr || Py_TYPE(d) != &PyMemberDescr_Type) return -1;
  const PyMemberDef* m = reinterpret_cast<PyMemberDescrObject*>(d)->d_member;
  if (m->type != T_OBJECT_EX || (m->flags & READ_RESTRICTED) != 0) return -1;
  return m->offset;
}

// A new reference to the attribute (nullptr with an exception set, as PyObject_GetAttr).
inline PyObject* get_field(PyObject* message, PyObject* name, Py_ssize_t slot) {
  if (slot >= 0) {
    PyObject* v = *reinterpret_cast<PyObject**>(reinterpret_cast<char*>(message) + slot);
    if (v != nullptr) {
      Py_INCREF(v);
      return v;
    }
  }
  return PyObject_GetAttr(message, name);  // unset slot: the AttributeError, as getattr says it
}

// A topic of fixed-size messages: its class, row layout, the block being filled, and the Python callable that
// takes what does not fit the layout.
struct FixedTopic {
  py::object cls;
  std::vector<std::uint8_t> row_template;
  std::vector<ScalarField> scalars;
  std::vector<ArrayField> arrays;
  std::vector<py::object> absent;
  std::shared_ptr<const std::vector<ViewSpec>> views;
  std::uint16_t channel = 0;
  std::size_t limit = 1;
  py::object slow;
  Block block;
};

class LogCore {
 public:
  LogCore(int fd, const std::string& compression, bool background, py::object other)
      : other_(std::move(other)), topics_(py::dict()) {
    if (!PyCallable_Check(other_.ptr())) throw py::type_error("other must be callable");
    writer_ = std::make_unique<ChunkWriter>(fd, logs::compression_from_name(compression), background);
  }

  // Registers a topic of fixed-size messages; returns its slot.
  std::size_t add_fixed_topic(
      py::object topic, py::object cls, std::uint16_t channel, py::bytes row_template,
      const std::vector<std::tuple<std::string, char, std::size_t>>& scalars,
      const std::vector<std::tuple<std::string, py::object, std::size_t, std::size_t>>& arrays,
      const std::vector<std::string>& absent,
      const std::vector<
          std::tuple<std::uint16_t, py::bytes, std::vector<std::tuple<std::size_t, std::size_t, std::size_t>>,
                     std::vector<std::tuple<std::size_t, std::size_t, std::size_t>>,
                     std::vector<std::tuple<std::size_t, std::size_t, std::size_t>>>>& views,
      std::size_t limit, py::object slow) {
    auto t = std::make_unique<FixedTopic>();
    t->cls = std::move(cls);
    const std::string tmpl = row_template;
    t->row_template.assign(tmpl.begin(), tmpl.end());
    const std::size_t size = t->row_template.size();
    for (const auto& [name, code, offset] : scalars) {
      if (code != 'd' && code != 'q' && code != '?') throw py::value_error("scalars: each code 'd', 'q' or '?'");
      if (offset + (code == '?' ? 1 : 8) > size) throw py::value_error("scalars: a field outside the row");
      py::str attr(name);
      t->scalars.push_back({attr, code, offset, slot_offset(t->cls, attr)});
    }
    const py::object dtype_type = py::module_::import("numpy").attr("dtype");
    for (const auto& [name, dtype, nbytes, offset] : arrays) {
      if (!py::isinstance(dtype, dtype_type)) throw py::type_error("arrays: numpy dtypes");
      const auto itemsize = static_cast<std::size_t>(py::dtype::from_args(dtype).itemsize());
      if (nbytes == 0 || nbytes % itemsize != 0 || offset + nbytes > size) {
        throw py::value_error("arrays: each > 0 bytes, a multiple of its itemsize, inside the row");
      }
      py::str attr(name);
      t->arrays.push_back(
          {attr, dtype, static_cast<py::ssize_t>(nbytes / itemsize), nbytes, offset, slot_offset(t->cls, attr)});
    }
    for (const auto& n : absent) t->absent.push_back(py::str(n));
    auto specs = std::make_shared<std::vector<ViewSpec>>();
    for (const auto& [view_channel, view_template, copies, stamps, rotations] : views) {
      ViewSpec v;
      v.channel = view_channel;
      const std::string vt = view_template;
      v.row_template.assign(vt.begin(), vt.end());
      for (const auto& [dst, src, bytes] : copies) {
        if (dst + bytes > v.row_template.size() || src + bytes > size)
          throw py::value_error("views: copy outside a row");
        v.copies.push_back({dst, src, bytes});
      }
      for (const auto& [sec, nsec, src] : stamps) {
        if (sec + 4 > v.row_template.size() || nsec + 4 > v.row_template.size() || src + 8 > size) {
          throw py::value_error("views: stamp outside a row");
        }
        v.stamps.push_back({sec, nsec, src});
      }
      for (const auto& [dst, src_v, src_q] : rotations) {
        if (dst + 24 > v.row_template.size() || src_v + 24 > size || src_q + 32 > size) {
          throw py::value_error("views: rotation outside a row");
        }
        v.rotations.push_back({dst, src_v, src_q});
      }
      specs->push_back(std::move(v));
    }
    t->views = std::move(specs);
    t->channel = channel;
    t->limit = std::max<std::size_t>(limit, 1);
    t->slow = std::move(slow);
    if (!PyCallable_Check(t->slow.ptr())) throw py::type_error("slow must be callable");
    start_block(*t);
    fixed_.push_back(std::move(t));
    const std::size_t slot = fixed_.size() - 1;
    topics_[topic] = py::int_(slot);
    return slot;
  }

  // The per-message entry (McapLogger.write): a registered fixed topic's message is packed here, any other
  // message goes to other(topic, message, log, publish, sequence).
  void write(PyObject* topic, PyObject* message, PyObject* log, PyObject* publish) {
    PyObject* slot = PyDict_GetItemWithError(topics_.ptr(), topic);  // borrowed
    const std::uint64_t sequence = sequence_++;
    if (slot == nullptr) {
      if (PyErr_Occurred()) throw py::error_already_set();
      py::object seq = py::int_(sequence);
      other_(py::handle(topic), py::handle(message), py::handle(log), py::handle(publish), seq);
      return;
    }
    add(*fixed_[PyLong_AsSize_t(slot)], message, log, publish, sequence);
  }

  // Adds a message to a fixed topic with a sequence number already drawn (McapLogger's first message of a topic).
  void add_with_sequence(std::size_t slot, py::handle message, py::handle log, py::handle publish,
                         std::uint64_t sequence) {
    add(*fixed_.at(slot), message.ptr(), log.ptr(), publish.ptr(), sequence);
  }

  // A block of already encoded messages of one channel (the Python codecs' topics).
  void write_payloads(std::uint16_t channel, const std::vector<py::bytes>& payloads,
                      const std::vector<std::uint64_t>& log, const std::vector<std::uint64_t>& publish,
                      const std::vector<std::uint64_t>& sequence) {
    if (payloads.empty()) return;
    if (log.size() != payloads.size() || publish.size() != payloads.size() || sequence.size() != payloads.size()) {
      throw py::value_error("write_payloads: one log time, publish time and sequence per payload");
    }
    Block b;
    b.channel = channel;
    for (const auto& p : payloads) {
      char* data;
      py::ssize_t n;
      PyBytes_AsStringAndSize(p.ptr(), &data, &n);
      b.data.insert(b.data.end(), data, data + n);
      b.ends.push_back(b.data.size());
    }
    b.log = log;
    b.publish = publish;
    for (const auto s : sequence) b.sequence.push_back(static_cast<std::uint32_t>(s));
    submit_block(std::move(b));
  }

  void write_records(py::bytes records) {
    char* data;
    py::ssize_t n;
    PyBytes_AsStringAndSize(records.ptr(), &data, &n);
    std::vector<std::uint8_t> v(data, data + n);
    waiting_for_disk([&] { writer_->write(std::move(v)); });
  }

  // Hands a fixed topic's partial block to the writer.
  void flush(std::size_t slot) {
    FixedTopic& t = *fixed_.at(slot);
    if (t.block.size()) {
      Block b = std::move(t.block);
      start_block(t);
      submit_block(std::move(b));
    }
  }

  std::size_t pending(std::size_t slot) const { return fixed_.at(slot)->block.size(); }

  void finish() {
    py::gil_scoped_release release;
    writer_->finish();
  }

  void close() {
    topics_.clear();
    py::gil_scoped_release release;
    writer_->close();
  }

  std::uint64_t position() const { return writer_->position(); }

  py::list chunks() const {
    py::list out;
    for (const auto& c : writer_->chunks()) {
      py::dict offsets;
      for (const auto& [channel, offset] : c.message_index_offsets) offsets[py::int_(channel)] = offset;
      out.append(py::make_tuple(c.start, c.end, c.chunk_start, c.chunk_length, offsets, c.message_index_length,
                                c.compressed_size, c.uncompressed_size));
    }
    return out;
  }

  py::dict message_counts() const {
    py::dict out;
    for (const auto& [channel, n] : writer_->message_counts()) out[py::int_(channel)] = n;
    return out;
  }

  py::object time_range() const {
    if (!writer_->any_message()) return py::none();
    return py::make_tuple(writer_->start_time(), writer_->end_time());
  }

 private:
  void start_block(FixedTopic& t) {
    t.block = Block();
    t.block.channel = t.channel;
    t.block.row_bytes = t.row_template.size();
    t.block.views = t.views;
    t.block.data.reserve(t.limit * t.row_template.size());
    t.block.log.reserve(t.limit);
    t.block.publish.reserve(t.limit);
    t.block.sequence.reserve(t.limit);
  }

  void add(FixedTopic& t, PyObject* message, PyObject* log, PyObject* publish, std::uint64_t sequence) {
    Block& b = t.block;
    const std::size_t start = b.data.size();
    std::uint64_t log_ns, publish_ns;
    b.data.resize(start + t.row_template.size());
    std::uint8_t* row = b.data.data() + start;
    if (!(Py_TYPE(message) == reinterpret_cast<PyTypeObject*>(t.cls.ptr()) && get_time(log, &log_ns) &&
          get_time(publish, &publish_ns) && pack(t, message, row))) {
      PyErr_Clear();
      b.data.resize(start);
      // the checked path: (row bytes, log, publish) or an exception naming what is wrong
      py::tuple r = t.slow(py::handle(message), py::handle(log), py::handle(publish));
      const std::string bytes = r[0].cast<std::string>();
      if (bytes.size() != t.row_template.size()) throw std::logic_error("slow: a row of the wrong size");
      b.data.insert(b.data.end(), bytes.begin(), bytes.end());
      log_ns = r[1].cast<std::uint64_t>();
      publish_ns = r[2].cast<std::uint64_t>();
    }
    b.log.push_back(log_ns);
    b.publish.push_back(publish_ns);
    b.sequence.push_back(static_cast<std::uint32_t>(sequence));  // mod 2^32, as MCAP's field
    if (b.size() >= t.limit) {
      Block full = std::move(b);
      start_block(t);
      submit_block(std::move(full));
    }
  }

  void submit_block(Block b) {
    waiting_for_disk([&] { writer_->chunk(std::move(b)); });
  }

  // Runs f (a hand-over to the writer), without the GIL when the writer's queue is full: f then waits for the
  // disk, and other Python threads run meanwhile. (The writer's std::system_error becomes OSError through the
  // translator define_logs registers.)
  template <typename F>
  void waiting_for_disk(F&& f) {
    if (writer_->full()) {
      py::gil_scoped_release release;
      f();
    } else {
      f();
    }
  }

  // A time: a Python int in [0, 2^63) (anything else, up to 2^64 included, takes the checked path, which
  // names what is wrong). PyLong_AsLongAndOverflow sums the digits; the unsigned conversions go through a byte
  // array, ten times the instructions.
  static bool get_time(PyObject* v, std::uint64_t* out) {
    if (!PyLong_CheckExact(v)) return false;
    int overflow = 0;
    const long long x = PyLong_AsLongLongAndOverflow(v, &overflow);
    if (overflow != 0 || x < 0) return false;
    *out = static_cast<std::uint64_t>(x);
    return true;
  }

  static bool pack(const FixedTopic& t, PyObject* message, std::uint8_t* row) {
    std::memcpy(row, t.row_template.data(), t.row_template.size());
    for (const auto& s : t.scalars) {
      PyObject* v = get_field(message, s.name.ptr(), s.slot);
      if (v == nullptr) return false;
      bool ok = true;
      if (s.code == 'd') {
        const double x = PyFloat_AsDouble(v);  // floats, ints and anything with __float__, as struct's 'd'
        ok = !(x == -1.0 && PyErr_Occurred());
        std::memcpy(row + s.offset, &x, 8);
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
        const auto y = static_cast<std::int64_t>(x);
        std::memcpy(row + s.offset, &y, 8);
      } else {
        const int b = PyObject_IsTrue(v);
        ok = b >= 0;
        row[s.offset] = static_cast<std::uint8_t>(b == 1);
      }
      Py_DECREF(v);
      if (!ok) return false;
    }
    auto& api = py::detail::npy_api::get();
    for (const auto& a : t.arrays) {
      PyObject* v = get_field(message, a.name.ptr(), a.slot);
      if (v == nullptr) return false;
      bool ok = api.PyArray_Check_(v) != 0;
      if (ok) {
        const auto* arr = py::detail::array_proxy(v);
        ok = arr->descr == a.dtype.ptr() && (arr->flags & py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_) != 0;
        if (ok) {
          py::ssize_t n = 1;
          for (int d = 0; d < arr->nd; ++d) n *= arr->dimensions[d];
          ok = n == a.elements;  // the dtype is the layout's, so equal counts mean equal bytes
          if (ok) std::memcpy(row + a.offset, arr->data, a.nbytes);
        }
      }
      Py_DECREF(v);
      if (!ok) return false;
    }
    for (const auto& name : t.absent) {
      PyObject* v = PyObject_GetAttr(message, name.ptr());
      if (v == nullptr) return false;
      const bool ok = v == Py_None;
      Py_DECREF(v);
      if (!ok) return false;
    }
    return true;
  }

  py::object other_;
  py::dict topics_;  // topic -> slot in fixed_
  std::vector<std::unique_ptr<FixedTopic>> fixed_;
  std::unique_ptr<ChunkWriter> writer_;
  std::uint64_t sequence_ = 0;
};

// `write` as a plain METH_FASTCALL builtin bound to a capsule holding the core and a strong reference to its
// Python object: pybind11's dispatcher (overload resolution, argument casters) would cost more than the packing.
struct WriteBinding {
  LogCore* core;
  PyObject* owner;
};

void write_binding_free(PyObject* capsule) {
  auto* b = static_cast<WriteBinding*>(PyCapsule_GetPointer(capsule, nullptr));
  if (b == nullptr) return;
  Py_XDECREF(b->owner);
  delete b;
}

PyObject* fast_write(PyObject* capsule, PyObject* const* args, Py_ssize_t nargs) {
  if (nargs != 4) {
    PyErr_Format(PyExc_TypeError, "write(topic, message, log_time_ns, publish_time_ns) takes 4 arguments, got %zd",
                 nargs);
    return nullptr;
  }
  auto* b = static_cast<WriteBinding*>(PyCapsule_GetPointer(capsule, nullptr));
  if (b == nullptr) return nullptr;
  try {
    b->core->write(args[0], args[1], args[2], args[3]);
    Py_RETURN_NONE;
  } catch (py::error_already_set& e) {
    e.restore();
    return nullptr;
  } catch (const std::logic_error& e) {
    PyErr_SetString(PyExc_RuntimeError, e.what());
    return nullptr;
  } catch (const std::exception& e) {
    PyErr_SetString(PyExc_OSError, e.what());
    return nullptr;
  }
}

PyMethodDef fast_write_def = {"write", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)(void)>(fast_write)),
                              METH_FASTCALL, "write(topic, message, log_time_ns, publish_time_ns): logs one message."};

py::object fast_writer(py::object self) {
  auto* b = new WriteBinding{self.cast<LogCore*>(), self.ptr()};
  Py_INCREF(self.ptr());
  // unnamed: GetPointer then compares names by pointer, not with strcmp on every call (the capsule is only ever
  // this builtin's self)
  PyObject* capsule = PyCapsule_New(b, nullptr, write_binding_free);
  if (capsule == nullptr) {
    Py_DECREF(b->owner);
    delete b;
    throw py::error_already_set();
  }
  PyObject* f = PyCFunction_NewEx(&fast_write_def, capsule, nullptr);
  Py_DECREF(capsule);
  if (f == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::object>(f);
}

}  // namespace

void define_logs(py::module_& m) {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const std::system_error& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    }
  });
  py::class_<LogCore>(m, "LogCore",
                      "The hot path of cufund.logs.McapLogger: fixed-size messages packed into CDR rows per topic, "
                      "blocks encoded, compressed and written by a C++ thread. Owns the file descriptor `fd`.")
      .def(py::init<int, const std::string&, bool, py::object>(), py::arg("fd"), py::arg("compression"),
           py::arg("background"), py::arg("other"))
      .def("add_fixed_topic", &LogCore::add_fixed_topic, py::arg("topic"), py::arg("cls"), py::arg("channel"),
           py::arg("row_template"), py::arg("scalars"), py::arg("arrays"), py::arg("absent"), py::arg("views"),
           py::arg("limit"), py::arg("slow"),
           "Registers a topic of fixed-size messages (scalars: (attr, 'd'|'q'|'?', offset); arrays: (attr, dtype, "
           "nbytes, offset); absent: attrs that must be None; views: (channel, template, copies (dst, src, "
           "bytes), stamps (sec, nsec, src t), rotations (dst, src v, src q [w, x, y, z]): dst = R(q)^T v); "
           "slow(message, log, publish) -> (row, log, publish)); its slot.")
      .def_property_readonly("write", &fast_writer,
                             "write(topic, message, log_time_ns, publish_time_ns) as a plain builtin.")
      .def("add_with_sequence", &LogCore::add_with_sequence, py::arg("slot"), py::arg("message"), py::arg("log"),
           py::arg("publish"), py::arg("sequence"))
      .def("write_payloads", &LogCore::write_payloads, py::arg("channel"), py::arg("payloads"), py::arg("log"),
           py::arg("publish"), py::arg("sequence"), "One chunk of already encoded messages of one channel.")
      .def("write_records", &LogCore::write_records, py::arg("records"), "Raw records, after what was submitted.")
      .def("flush", &LogCore::flush, py::arg("slot"), "Hands a fixed topic's partial block to the writer.")
      .def("pending", &LogCore::pending, py::arg("slot"), "Messages of a fixed topic not yet handed over.")
      .def("finish", &LogCore::finish, "Waits until everything submitted is in the file.")
      .def("close", &LogCore::close, "Finishes and closes the file.")
      .def_property_readonly("position", &LogCore::position, "The file position (after finish).")
      .def("chunks", &LogCore::chunks,
           "(start, end, chunk_start, chunk_length, message index offsets, message index length, compressed size, "
           "uncompressed size) of every chunk written.")
      .def("message_counts", &LogCore::message_counts, "Messages written per channel.")
      .def("time_range", &LogCore::time_range, "(first, last) log time written [ns], or None.");
}

}  // namespace cufund::py_bind
