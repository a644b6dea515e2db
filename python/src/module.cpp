// SPDX-License-Identifier: Apache-2.0
// python/src/module.cpp: the extension module psq._psq (pybind11). It
// moves arrays between numpy and binding.h's C++ buffers: results are
// handed to numpy without copies (each buffer moves into a capsule that
// becomes the array's base), inputs are read in place from C-contiguous
// arrays. Every call into the library releases the GIL. The public API,
// docstrings and argument checks are in python/psq/__init__.py.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <mutex>
#include <utility>

#include "binding.h"
#include "psq/sequence.h"

namespace py = pybind11;

namespace psq::python {
namespace {

// ------------------------------------------------------------------- text

// Text from the library as Python str. Messages, notes and property names
// may quote bytes of a hostile input that are not UTF-8: they are replaced
// (U+FFFD), so that reporting an error never fails itself. File names are
// decoded as the file system's (surrogateescape), so that they round-trip.
py::str text(const std::string& s) {
  PyObject* o = PyUnicode_DecodeUTF8(s.data(), static_cast<Py_ssize_t>(s.size()), "replace");
  if (o == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

py::str file_name(const std::string& s) {
  PyObject* o = PyUnicode_DecodeFSDefaultAndSize(s.data(), static_cast<Py_ssize_t>(s.size()));
  if (o == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

py::list texts(const std::vector<std::string>& v) {
  py::list l;
  for (const std::string& s : v) l.append(text(s));
  return l;
}

// --------------------------------------------------------------- arrays out

template <class V>
py::array hand_over(V&& v, std::vector<py::ssize_t> shape, const py::dtype& dtype) {
  auto* held = new V(std::move(v));
  if (held->data() == nullptr) held->reserve(1);  // numpy wants a pointer even for no element
  py::capsule base(held, [](void* p) { delete static_cast<V*>(p); });
  return py::array(dtype, std::move(shape), held->data(), base);
}

py::dtype dtype_of(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8: return py::dtype::of<int8_t>();
    case ScalarType::kUInt8: return py::dtype::of<uint8_t>();
    case ScalarType::kInt16: return py::dtype::of<int16_t>();
    case ScalarType::kUInt16: return py::dtype::of<uint16_t>();
    case ScalarType::kInt32: return py::dtype::of<int32_t>();
    case ScalarType::kUInt32: return py::dtype::of<uint32_t>();
    case ScalarType::kFloat32: return py::dtype::of<float>();
    case ScalarType::kFloat64: return py::dtype::of<double>();
  }
  return py::dtype::of<double>();
}

ScalarType scalar_from_dtype(const py::dtype& dt, const std::string& what) {
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (kind == 'f' && size == 4) return ScalarType::kFloat32;
  if (kind == 'f' && size == 8) return ScalarType::kFloat64;
  if (kind == 'i' && size == 1) return ScalarType::kInt8;
  if (kind == 'i' && size == 2) return ScalarType::kInt16;
  if (kind == 'i' && size == 4) return ScalarType::kInt32;
  if (kind == 'u' && size == 1) return ScalarType::kUInt8;
  if (kind == 'u' && size == 2) return ScalarType::kUInt16;
  if (kind == 'u' && size == 4) return ScalarType::kUInt32;
  usage(what + ": dtype " + py::str(dt.attr("name")).cast<std::string>() +
        " is not one psq stores (int8/16/32, uint8/16/32, float32, float64)");
}

// Scalar columns become 1-D arrays; list columns a tuple (counts, values,
// count type name) that psq/__init__.py wraps in a ListProperty.
py::dict columns_out(std::vector<Column>& cols) {
  py::dict d;
  for (Column& c : cols) {
    const auto width = static_cast<py::ssize_t>(scalar_size(c.prop.type));
    const auto values = static_cast<py::ssize_t>(c.values.size()) / width;
    py::array v = hand_over(std::move(c.values), {values}, dtype_of(c.prop.type));
    if (!c.prop.is_list) {
      d[text(c.prop.name)] = v;
    } else {
      const auto count = static_cast<py::ssize_t>(c.counts.size());
      py::array counts = hand_over(std::move(c.counts), {count}, py::dtype::of<uint32_t>());
      d[text(c.prop.name)] = py::make_tuple(counts, v, scalar_name(c.prop.count_type));
    }
  }
  return d;
}

py::dict mesh_out(MeshData& m) {
  py::dict d;
  const auto nv = static_cast<py::ssize_t>(m.vertex_count());
  if (m.position_type == ScalarType::kFloat64)
    d["positions"] = hand_over(std::move(m.positions_d), {nv, 3}, py::dtype::of<double>());
  else
    d["positions"] = hand_over(std::move(m.positions_f), {nv, 3}, py::dtype::of<float>());
  const auto nt = static_cast<py::ssize_t>(m.faces.size() / 3);
  d["faces"] = hand_over(std::move(m.faces), {nt, 3}, py::dtype::of<uint32_t>());
  d["vertex_properties"] = columns_out(m.vertex_properties);
  d["face_properties"] = columns_out(m.face_properties);
  d["format"] = m.format;
  d["notes"] = texts(m.notes);
  return d;
}

// ---------------------------------------------------------------- arrays in

// The buffer of a C-contiguous array (psq/__init__.py makes them so).
const void* contiguous(const py::array& a, const std::string& what) {
  if (!(a.flags() & py::array::c_style)) usage(what + " must be C-contiguous");
  return a.data();
}

// cols: a list of (name, values, counts or None, count type name).
std::vector<InColumn> columns_in(const py::list& cols, const char* what) {
  std::vector<InColumn> out;
  for (const py::handle& item : cols) {
    const py::tuple t = py::reinterpret_borrow<py::tuple>(item);
    InColumn c;
    c.prop.name = t[0].cast<std::string>();
    const py::array values = t[1].cast<py::array>();
    const std::string label = std::string(what) + " property '" + c.prop.name + "'";
    if (values.ndim() != 1) usage(label + " must be a 1-D array");
    c.prop.type = scalar_from_dtype(values.dtype(), label);
    c.values = contiguous(values, label);
    c.value_count = static_cast<uint64_t>(values.shape(0));
    if (!t[2].is_none()) {
      const py::array counts = t[2].cast<py::array>();
      if (counts.ndim() != 1 || counts.dtype().kind() != 'u' || counts.dtype().itemsize() != 4)
        usage(label + ": list counts must be a 1-D uint32 array");
      c.prop.is_list = true;
      c.counts = static_cast<const uint32_t*>(contiguous(counts, label));
      const std::string ct = t[3].cast<std::string>();
      if (ct == "uchar" || ct == "uint8") c.prop.count_type = ScalarType::kUInt8;
      else if (ct == "ushort" || ct == "uint16") c.prop.count_type = ScalarType::kUInt16;
      else if (ct == "uint" || ct == "uint32") c.prop.count_type = ScalarType::kUInt32;
      else usage(label + ": count type must be uint8, uint16 or uint32");
    }
    out.push_back(std::move(c));
  }
  return out;
}

// Arrays the caller passes stay referenced by the py::objects in this
// struct while the GIL is released.
struct InArrays {
  py::array positions, faces;
  py::list vertex_props, face_props;
  InMesh mesh;
};

void fill_in(InArrays* in) {
  const py::array& p = in->positions;
  const py::array& f = in->faces;
  if (p.ndim() != 2 || p.shape(1) != 3) usage("positions must be an N x 3 array");
  if (f.ndim() != 2 || f.shape(1) != 3) usage("faces must be an M x 3 array");
  const ScalarType pt = scalar_from_dtype(p.dtype(), "positions");
  if (pt != ScalarType::kFloat32 && pt != ScalarType::kFloat64) usage("positions must be float32 or float64");
  if (f.dtype().kind() != 'u' || f.dtype().itemsize() != 4) usage("faces must be uint32");
  in->mesh.positions = contiguous(p, "positions");
  in->mesh.positions_double = pt == ScalarType::kFloat64;
  in->mesh.vertices = static_cast<uint64_t>(p.shape(0));
  in->mesh.faces = static_cast<const uint32_t*>(contiguous(f, "faces"));
  in->mesh.triangles = static_cast<uint64_t>(f.shape(0));
  in->mesh.vertex_properties = columns_in(in->vertex_props, "vertex");
  in->mesh.face_properties = columns_in(in->face_props, "face");
}

WriteParams write_params(const py::dict& o) {
  WriteParams w;
  if (o.contains("format") && !o["format"].is_none()) w.format = o["format"].cast<std::string>();
  if (o.contains("bits")) w.bits = o["bits"].cast<int>();
  if (o.contains("lossless")) w.lossless = o["lossless"].cast<bool>();
  if (o.contains("normal_bits")) w.normal_bits = o["normal_bits"].cast<int>();
  if (o.contains("uv_bits")) w.uv_bits = o["uv_bits"].cast<int>();
  if (o.contains("profile")) w.profile = o["profile"].cast<std::string>();
  if (o.contains("chunk_bytes")) w.chunk_bytes = o["chunk_bytes"].cast<uint32_t>();
  if (o.contains("zstd_level")) w.zstd_level = o["zstd_level"].cast<int>();
  if (o.contains("ascii")) w.ascii = o["ascii"].cast<bool>();
  if (o.contains("overwrite")) w.overwrite = o["overwrite"].cast<bool>();
  if (o.contains("memory")) w.memory = o["memory"].cast<uint64_t>();
  if (o.contains("tmpdir") && !o["tmpdir"].is_none()) w.tmpdir = o["tmpdir"].cast<std::string>();
  return w;
}

InArrays arrays_in(py::array positions, py::array faces, py::list vprops, py::list fprops) {
  InArrays in;
  in.positions = std::move(positions);
  in.faces = std::move(faces);
  in.vertex_props = std::move(vprops);
  in.face_props = std::move(fprops);
  fill_in(&in);
  return in;
}

// A list column must have one count per element (binding.h's
// check_in_mesh() reads them all); checked before the GIL is released.
void check_count_lengths(const py::list& cols, uint64_t elements, const char* what) {
  for (const py::handle& item : cols) {
    const py::tuple t = py::reinterpret_borrow<py::tuple>(item);
    if (t[2].is_none()) continue;
    const py::array counts = t[2].cast<py::array>();
    if (static_cast<uint64_t>(counts.shape(0)) != elements)
      usage(std::string(what) + " property '" + t[0].cast<std::string>() + "' has " +
            std::to_string(counts.shape(0)) + " lists for " + std::to_string(elements) + " elements");
  }
}

// ---------------------------------------------------------------- streaming

class PyReader {
 public:
  // A path (str or bytes, as os.fsencode gives it) when `is_path`, else a
  // buffer of .psq bytes, read in place.
  PyReader(py::object source, bool is_path) {
    if (is_path) {
      const std::string path = source.cast<std::string>();
      py::gil_scoped_release release;
      reader_.open_path(path);
    } else {
      keep_ = source;
      buffer_ = py::buffer(source).request();
      const auto* data = static_cast<const uint8_t*>(buffer_.ptr);
      const auto size = static_cast<size_t>(buffer_.size * buffer_.itemsize);
      py::gil_scoped_release release;
      reader_.open_memory(data, size);
    }
  }

  py::object next(uint64_t max_triangles) {
    Chunk c;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      reader_.next(max_triangles, &c);
    }
    if (c.end) return py::none();
    py::dict d;
    const auto nv = static_cast<py::ssize_t>(c.reappears.size());
    const auto nt = static_cast<py::ssize_t>(c.ops.size());
    if (reader_.header().schema.position_type == ScalarType::kFloat64)
      d["positions"] = hand_over(std::move(c.positions_d), {nv, 3}, py::dtype::of<double>());
    else
      d["positions"] = hand_over(std::move(c.positions_f), {nv, 3}, py::dtype::of<float>());
    d["reappears"] = hand_over(std::move(c.reappears), {nv}, py::dtype::of<int64_t>());
    d["faces"] = hand_over(std::move(c.faces), {nt, 3}, py::dtype::of<uint32_t>());
    d["ops"] = hand_over(std::move(c.ops), {nt}, py::dtype::of<uint8_t>());
    d["new_mask"] = hand_over(std::move(c.new_mask), {nt}, py::dtype::of<uint8_t>());
    d["final_mask"] = hand_over(std::move(c.final_mask), {nt}, py::dtype::of<uint8_t>());
    d["border_mask"] = hand_over(std::move(c.border_mask), {nt}, py::dtype::of<uint8_t>());
    const auto nf = static_cast<py::ssize_t>(c.finalized.size());
    d["finalized"] = hand_over(std::move(c.finalized), {nf}, py::dtype::of<uint32_t>());
    d["vertex_properties"] = columns_out(c.vertex_properties);
    d["face_properties"] = columns_out(c.face_properties);
    d["vertex_start"] = c.vertex_start;
    d["triangle_start"] = c.triangle_start;
    return std::move(d);
  }

  py::dict header() const {
    const PsqHeader& h = reader_.header();
    py::dict d;
    d["version"] = std::to_string(h.version_major) + "." + std::to_string(h.version_minor);
    d["lossless"] = h.lossless;
    d["profile"] = h.fast ? "fast" : "compact";
    d["bits"] = h.bits;
    d["step"] = h.step;
    d["origin"] = py::make_tuple(h.origin[0], h.origin[1], h.origin[2]);
    d["boundary_limit"] = h.boundary_limit;
    d["position_type"] = scalar_name(h.schema.position_type);
    d["vertex_count"] = h.schema.vertex_count >= 0 ? py::int_(h.schema.vertex_count) : py::object(py::none());
    d["triangle_count"] = h.schema.triangle_count >= 0 ? py::int_(h.schema.triangle_count) : py::object(py::none());
    py::list vp, fp;
    for (const Property& p : h.schema.vertex_properties) vp.append(py::make_tuple(text(p.name), scalar_name(p.type), p.is_list));
    for (const Property& p : h.schema.face_properties) fp.append(py::make_tuple(text(p.name), scalar_name(p.type), p.is_list));
    d["vertex_properties"] = vp;
    d["face_properties"] = fp;
    return d;
  }

  py::dict stats() {
    PsqStats s;
    {
      py::gil_scoped_release release;  // a next() on another thread may be filling them
      std::lock_guard<std::mutex> lock(mutex_);
      s = reader_.stats();
    }
    py::dict d;
    d["vertices"] = s.vertices;
    d["triangles"] = s.triangles;
    d["chunks"] = s.chunks;
    d["total_bytes"] = s.total_bytes;
    d["max_active_vertices"] = s.max_active_vertices;
    d["max_open_edges"] = s.max_open_edges;
    return d;
  }

  void close() {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    reader_.close();
  }

 private:
  StreamReader reader_;
  py::object keep_;  // the bytes read in place
  py::buffer_info buffer_;
  std::mutex mutex_;
};

}  // namespace
}  // namespace psq::python

PYBIND11_MODULE(_psq, m) {
  using namespace psq::python;
  m.doc() = "The C++ half of psq (see the psq package for the documented API).";

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const StatusError& e) {
      const psq::Status& s = e.status();
      py::object offset = s.offset() == psq::Status::kNoPlace ? py::object(py::none()) : py::int_(s.offset());
      py::object line = s.line() == psq::Status::kNoPlace ? py::object(py::none()) : py::int_(s.line());
      py::object file = e.file().empty() ? py::object(py::none()) : py::object(file_name(e.file()));
      py::object error = py::module_::import("psq._errors")
                             .attr("_from_status")(static_cast<int>(s.code()), text(s.message()), offset, line, file);
      PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(error.ptr())), error.ptr());
    }
  });

  m.def("read_path", [](const std::string& path) {
    MeshData data;
    {
      py::gil_scoped_release release;
      read_path(path, &data);
    }
    return mesh_out(data);
  });
  m.def("read_buffer", [](const py::buffer& source) {
    py::buffer_info info = source.request();
    const auto* bytes = static_cast<const uint8_t*>(info.ptr);
    const auto size = static_cast<size_t>(info.size * info.itemsize);
    MeshData data;
    {
      py::gil_scoped_release release;
      read_memory(bytes, size, "<memory>", &data);
    }
    return mesh_out(data);
  });
  m.def("write", [](const std::string& path, py::array positions, py::array faces, py::list vprops, py::list fprops,
                    py::dict options) {
    InArrays in = arrays_in(std::move(positions), std::move(faces), std::move(vprops), std::move(fprops));
    check_count_lengths(in.vertex_props, in.mesh.vertices, "vertex");
    check_count_lengths(in.face_props, in.mesh.triangles, "face");
    const WriteParams w = write_params(options);
    std::vector<std::string> notes;
    {
      py::gil_scoped_release release;
      notes = write_path(in.mesh, path, w);
    }
    return texts(notes);
  });
  m.def("encode", [](py::array positions, py::array faces, py::list vprops, py::list fprops, py::dict options) {
    InArrays in = arrays_in(std::move(positions), std::move(faces), std::move(vprops), std::move(fprops));
    check_count_lengths(in.vertex_props, in.mesh.vertices, "vertex");
    check_count_lengths(in.face_props, in.mesh.triangles, "face");
    const WriteParams w = write_params(options);
    std::vector<uint8_t> out;
    {
      py::gil_scoped_release release;
      encode_bytes(in.mesh, w, &out);
    }
    return py::bytes(reinterpret_cast<const char*>(out.data()), out.size());
  });

  py::class_<PyReader>(m, "Reader")
      .def(py::init<py::object, bool>())
      .def("next", &PyReader::next)
      .def("header", &PyReader::header)
      .def("stats", &PyReader::stats)
      .def("close", &PyReader::close);

  m.def("convert", [](const std::string& in, const std::string& out, py::dict o) {
    ConvertParams p;
    p.write = write_params(o);
    if (o.contains("threads")) p.threads = o["threads"].cast<int>();
    if (o.contains("weld")) p.weld = o["weld"].cast<std::string>();
    if (o.contains("measure_costs")) p.measure_costs = o["measure_costs"].cast<bool>();
    std::string json;
    {
      py::gil_scoped_release release;
      json = convert(in, out, p);
    }
    return text(json);
  });
  m.def("simplify", [](const std::string& in, const std::string& out, py::dict o) {
    SimplifyParams p;
    auto get = [&](const char* k) { return o.contains(k) && !o[k].is_none(); };
    if (get("method")) p.method = o["method"].cast<std::string>();
    if (get("ratio")) p.ratio = o["ratio"].cast<double>();
    if (get("triangles")) p.triangles = o["triangles"].cast<uint64_t>();
    if (get("grid")) p.grid = o["grid"].cast<double>();
    if (get("cell")) p.cell = o["cell"].cast<double>();
    if (get("cells")) p.cells = o["cells"].cast<std::string>();
    if (get("border_weight")) p.border_weight = o["border_weight"].cast<double>();
    if (get("max_error")) p.qem.max_error = o["max_error"].cast<double>();
    if (get("buffer")) p.qem.buffer_triangles = o["buffer"].cast<uint32_t>();
    if (get("candidates")) p.qem.candidates = o["candidates"].cast<int>();
    if (get("lock_border")) p.qem.lock_border = o["lock_border"].cast<bool>();
    if (get("seed")) p.qem.seed = o["seed"].cast<uint64_t>();
    if (get("format")) p.format = o["format"].cast<std::string>();
    if (get("bits")) p.bits = o["bits"].cast<int>();
    if (get("lossless")) p.lossless = o["lossless"].cast<bool>();
    if (get("profile")) p.profile = o["profile"].cast<std::string>();
    if (get("ascii")) p.ascii = o["ascii"].cast<bool>();
    if (get("overwrite")) p.overwrite = o["overwrite"].cast<bool>();
    if (get("memory")) p.memory = o["memory"].cast<uint64_t>();
    if (get("tmpdir")) p.tmpdir = o["tmpdir"].cast<std::string>();
    std::string json;
    {
      py::gil_scoped_release release;
      json = simplify(in, out, p);
    }
    return text(json);
  });
  m.def("info", [](const std::string& path, uint64_t memory, const std::string& tmpdir) {
    InfoParams p;
    p.memory = memory;
    p.tmpdir = tmpdir;
    std::string json;
    {
      py::gil_scoped_release release;
      json = info(path, p);
    }
    return text(json);
  });
  m.def("distance", [](const std::string& a, const std::string& b, uint64_t samples, uint64_t seed, int threads,
                       const std::string& hold, const std::string& tmpdir) {
    DistanceParams p;
    p.samples = samples;
    p.seed = seed;
    p.threads = threads;
    p.hold = hold;
    p.tmpdir = tmpdir;
    std::string json;
    {
      py::gil_scoped_release release;
      json = distance(a, b, p);
    }
    return text(json);
  });
  m.def("error_name", [](int code) { return psq::error_name(static_cast<psq::ErrorCode>(code)); });
  py::list ops;
  for (int i = 0; i <= 4; ++i) ops.append(psq::op_name(static_cast<psq::Op>(i)));
  m.attr("OPS") = py::tuple(ops);
}
