// SPDX-License-Identifier: Apache-2.0
#include "test_util.h"

#include <random>

#include <dirent.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "psq/mesh_formats.h"
#include "psq/sequence_builder.h"

namespace psq::test {

Status MemorySink::begin(const MeshSchema& schema) {
  mesh = Mesh();
  mesh.schema = schema;
  return Status();
}
Status MemorySink::vertex(const double p[3], const PropertyValues& values) {
  mesh.positions.push_back({p[0], p[1], p[2]});
  mesh.vertex_values.push_back(values);
  return Status();
}
Status MemorySink::triangle(const uint32_t idx[3], const PropertyValues& values) {
  mesh.triangles.push_back({idx[0], idx[1], idx[2]});
  mesh.face_values.push_back(values);
  return Status();
}
Status MemorySink::finish() {
  finished = true;
  return Status();
}

MemorySource::MemorySource(Mesh mesh) : mesh_(std::move(mesh)) {}

Status MemorySource::next(MeshItem* item) {
  size_t nv = mesh_.positions.size();
  if (at_ < nv) {
    item->kind = MeshItem::Kind::kVertex;
    for (int k = 0; k < 3; ++k) item->position[k] = mesh_.positions[at_][k];
    item->values = at_ < mesh_.vertex_values.size() ? mesh_.vertex_values[at_] : PropertyValues();
  } else if (at_ < nv + mesh_.triangles.size()) {
    size_t t = at_ - nv;
    item->kind = MeshItem::Kind::kTriangle;
    for (int k = 0; k < 3; ++k) item->index[k] = mesh_.triangles[t][k];
    item->values = t < mesh_.face_values.size() ? mesh_.face_values[t] : PropertyValues();
  } else {
    item->kind = MeshItem::Kind::kEnd;
    item->values.clear();
    return Status();
  }
  ++at_;
  return Status();
}

Mesh make_sphere(int rings, int segments) {
  Mesh m;
  const double pi = 3.14159265358979323846;
  m.positions.push_back({0, 0, 1});
  for (int r = 1; r < rings; ++r) {
    double th = pi * r / rings;
    for (int s = 0; s < segments; ++s) {
      double ph = 2 * pi * s / segments;
      // Round through float so that float files hold the positions exactly.
      volatile float x = static_cast<float>(std::sin(th) * std::cos(ph));
      volatile float y = static_cast<float>(std::sin(th) * std::sin(ph));
      volatile float z = static_cast<float>(std::cos(th));
      m.positions.push_back({x, y, z});
    }
  }
  m.positions.push_back({0, 0, -1});
  auto ring = [&](int r, int s) { return static_cast<uint32_t>(1 + (r - 1) * segments + (s % segments)); };
  uint32_t south = static_cast<uint32_t>(m.positions.size() - 1);
  for (int s = 0; s < segments; ++s) m.triangles.push_back({0, ring(1, s), ring(1, s + 1)});
  for (int r = 1; r + 1 < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      m.triangles.push_back({ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
      m.triangles.push_back({ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
    }
  }
  for (int s = 0; s < segments; ++s) m.triangles.push_back({south, ring(rings - 1, s + 1), ring(rings - 1, s)});
  m.vertex_values.assign(m.positions.size(), PropertyValues());
  m.face_values.assign(m.triangles.size(), PropertyValues());
  m.schema.vertex_count = static_cast<int64_t>(m.positions.size());
  m.schema.triangle_count = static_cast<int64_t>(m.triangles.size());
  return m;
}

void reset_values(Mesh* m) {
  m->vertex_values.assign(m->positions.size(), {});
  m->face_values.assign(m->triangles.size(), {});
  m->schema.vertex_count = static_cast<int64_t>(m->positions.size());
  m->schema.triangle_count = static_cast<int64_t>(m->triangles.size());
}

Mesh make_mesh(std::vector<std::array<double, 3>> positions, std::vector<std::array<uint32_t, 3>> triangles) {
  Mesh m;
  m.positions = std::move(positions);
  m.triangles = std::move(triangles);
  reset_values(&m);
  return m;
}

Mesh make_grid(int n) {
  Mesh m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.positions.push_back({static_cast<double>(i), static_cast<double>(j), 0.0});
  auto id = [n](int i, int j) { return static_cast<uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  m.vertex_values.assign(m.positions.size(), PropertyValues());
  m.face_values.assign(m.triangles.size(), PropertyValues());
  m.schema.vertex_count = static_cast<int64_t>(m.positions.size());
  m.schema.triangle_count = static_cast<int64_t>(m.triangles.size());
  return m;
}

void garble_first_chunk_records(std::vector<uint8_t>* bytes, uint32_t seed, int count) {
  std::vector<uint8_t>& b = *bytes;
  std::mt19937 rng(seed);
  // Spec 3.1: a varint at `at`, which moves past it.
  auto varint = [&](size_t& at) {
    uint64_t v = 0;
    for (int shift = 0;; shift += 7) {
      v |= static_cast<uint64_t>(b[at] & 0x7f) << shift;
      if (!(b[at++] & 0x80)) return v;
    }
  };
  // The first chunk starts after the header (spec 4.2, 4.3): tag, six
  // counts, the records, the properties, the checksum.
  size_t at = 12;
  const uint64_t payload = varint(at);
  const size_t chunk = at + payload + 4;
  ASSERT_EQ(b[chunk], 0x43);
  at = chunk + 1;
  uint64_t field[6];
  for (uint64_t& f : field) f = varint(at);
  const size_t conn_at = at;
  const uint64_t conn = field[3], prop = field[4];
  for (int k = 0; k < count; ++k) b[conn_at + rng() % conn] = static_cast<uint8_t>(rng());
  // CRC-32C, bitwise.
  uint32_t c = 0xffffffffu;
  const size_t end = conn_at + conn + prop;
  for (size_t i = chunk; i < end; ++i) {
    c ^= b[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0x82f63b78u & (0u - (c & 1u)));
  }
  c = ~c;
  for (int k = 0; k < 4; ++k) b[end + k] = static_cast<uint8_t>(c >> (8 * k));
}

std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  EXPECT_TRUE(f.good()) << "cannot read " << path;
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

void write_file(const std::string& path, const std::string& contents) {
  std::ofstream f(path, std::ios::binary);
  f << contents;
  ASSERT_TRUE(f.good()) << "cannot write " << path;
}

bool file_exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

TempDir::TempDir() {
  const char* env = std::getenv("TMPDIR");
  std::string tmpl = std::string(env != nullptr && *env != '\0' ? env : "/tmp") + "/psq-test-XXXXXX";
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  char* made = ::mkdtemp(buf.data());
  EXPECT_NE(made, nullptr);
  path_ = made != nullptr ? made : "/tmp";
}

TempDir::~TempDir() {
  for (const std::string& e : entries()) ::unlink((path_ + "/" + e).c_str());
  ::rmdir(path_.c_str());
}

std::vector<std::string> TempDir::entries() const {
  std::vector<std::string> out;
  DIR* d = ::opendir(path_.c_str());
  if (d == nullptr) return out;
  while (dirent* e = ::readdir(d)) {
    std::string n = e->d_name;
    if (n != "." && n != "..") out.push_back(n);
  }
  ::closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

int run_psq(const std::string& args, std::string* out, std::string* err, const std::string& stdin_file) {
  TempDir tmp;
  std::string cmd = std::string(PSQ_BINARY) + " " + args + " >" + tmp.file("out") + " 2>" + tmp.file("err");
  cmd += " <" + (stdin_file.empty() ? std::string("/dev/null") : stdin_file);
  int rc = std::system(cmd.c_str());
  if (out != nullptr) *out = read_file(tmp.file("out"));
  if (err != nullptr) *err = read_file(tmp.file("err"));
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : 128;
}

Status load_mesh(const std::string& path, Mesh* mesh) {
  OpenedMesh opened;
  PSQ_RETURN_IF_ERROR(open_mesh(path, OpenOptions(), &opened));
  MemorySink sink;
  PSQ_RETURN_IF_ERROR(pump(*opened.source, sink));
  *mesh = std::move(sink.mesh);
  return Status();
}

std::vector<std::array<uint32_t, 3>> canonical_triangles(const Mesh& mesh) {
  std::vector<std::array<uint32_t, 3>> out = mesh.triangles;
  for (auto& t : out) {
    while (t[0] > t[1] || t[0] > t[2]) std::rotate(t.begin(), t.begin() + 1, t.end());
  }
  std::sort(out.begin(), out.end());
  return out;
}

Mesh make_torus(int around, int across, double thickness) {
  Mesh m;
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < around; ++i) {
    const double u = 2 * pi * i / around;
    for (int j = 0; j < across; ++j) {
      const double v = 2 * pi * j / across;
      const double r = 1 + thickness * std::cos(v);
      volatile float x = static_cast<float>(r * std::cos(u));
      volatile float y = static_cast<float>(r * std::sin(u));
      volatile float z = static_cast<float>(thickness * std::sin(v));
      m.positions.push_back({x, y, z});
    }
  }
  auto id = [&](int i, int j) { return static_cast<uint32_t>((i % around) * across + (j % across)); };
  for (int i = 0; i < around; ++i) {
    for (int j = 0; j < across; ++j) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  reset_values(&m);
  return m;
}

Mesh shuffled(const Mesh& m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint32_t> perm(m.positions.size());
  for (uint32_t i = 0; i < perm.size(); ++i) perm[i] = i;
  std::shuffle(perm.begin(), perm.end(), rng);
  Mesh out = m;
  std::vector<uint32_t> where(perm.size());
  for (uint32_t i = 0; i < perm.size(); ++i) {
    out.positions[i] = m.positions[perm[i]];
    out.vertex_values[i] = m.vertex_values[perm[i]];
    where[perm[i]] = i;
  }
  for (auto& t : out.triangles) {
    for (uint32_t& v : t) v = where[v];
  }
  std::vector<size_t> order(out.triangles.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  Mesh o2 = out;
  for (size_t i = 0; i < order.size(); ++i) {
    o2.triangles[i] = out.triangles[order[i]];
    o2.face_values[i] = out.face_values[order[i]];
  }
  return o2;
}

Status EventLog::begin(const MeshSchema& s) {
  schema = s;
  return Status();
}

Status EventLog::vertex(const SequenceVertex& v) {
  events.emplace_back();
  events.back().kind = SequenceEvent::Kind::kVertex;
  events.back().vertex = v;
  return Status();
}

Status EventLog::triangle(const SequenceTriangle& t) {
  events.emplace_back();
  events.back().kind = SequenceEvent::Kind::kTriangle;
  events.back().triangle = t;
  return Status();
}

Status EventLog::finalize(uint32_t i) {
  events.emplace_back();
  events.back().kind = SequenceEvent::Kind::kFinalize;
  events.back().finalized = i;
  return Status();
}

Status EventLog::finish() {
  finished = true;
  return Status();
}

std::string EventLog::text() const {
  std::string s;
  char buf[256];
  for (const SequenceEvent& e : events) {
    if (e.kind == SequenceEvent::Kind::kVertex) {
      std::snprintf(buf, sizeof buf, "v %u %u %.17g %.17g %.17g", e.vertex.index, e.vertex.reappears,
                    e.vertex.position[0], e.vertex.position[1], e.vertex.position[2]);
      s += buf;
      for (double x : e.vertex.values) s += " " + std::to_string(x);
    } else if (e.kind == SequenceEvent::Kind::kTriangle) {
      std::snprintf(buf, sizeof buf, "t %u %u %u %d %d", e.triangle.v[0], e.triangle.v[1], e.triangle.v[2],
                    static_cast<int>(e.triangle.op), e.triangle.border_mask);
      s += buf;
      for (double x : e.triangle.values) s += " " + std::to_string(x);
    } else {
      s += "x " + std::to_string(e.finalized);
    }
    s += "\n";
  }
  return s;
}

Status EventReplay::next(SequenceEvent* e) {
  if (at_ < log_.events.size()) {
    *e = log_.events[at_++];
  } else {
    e->kind = SequenceEvent::Kind::kEnd;
  }
  return Status();
}

Mesh make_wavy_fan(uint32_t n) {
  std::vector<std::array<double, 3>> p{{0, 0, 0}};
  std::vector<std::array<uint32_t, 3>> t;
  for (uint32_t i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    // Through volatile floats: GCC 12's SLP vectorizer drops a
    // (double)(float) rounding (../shared/toolchain).
    volatile float x = static_cast<float>(std::cos(a)), y = static_cast<float>(std::sin(a)),
                   z = static_cast<float>(0.2 * std::sin(7 * a));
    p.push_back({x, y, z});
    t.push_back({0, 1 + i, 1 + (i + 1) % n});
  }
  return make_mesh(p, t);
}

EventLog build_events(const Mesh& mesh) {
  MemorySource src(mesh);
  EventLog ev;
  BuildReport report;
  const Status s = build_sequence(src, ev, BuildOptions(), &report);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return ev;
}

Status encode_sequence(const EventLog& ev, const EncodeOptions& o, std::vector<uint8_t>* bytes) {
  VectorWriter w(bytes);
  PsqEncoder enc(&w, o);
  PSQ_RETURN_IF_ERROR(enc.begin(ev.schema));
  for (const SequenceEvent& e : ev.events) {
    if (e.kind == SequenceEvent::Kind::kVertex) PSQ_RETURN_IF_ERROR(enc.vertex(e.vertex));
    else if (e.kind == SequenceEvent::Kind::kTriangle) PSQ_RETURN_IF_ERROR(enc.triangle(e.triangle));
    else PSQ_RETURN_IF_ERROR(enc.finalize(e.finalized));
  }
  return enc.finish();
}

EncodeOptions attribute_options(bool fast, int normal_bits, int uv_bits) {
  EncodeOptions o;
  o.bits = 14;
  o.fast = fast;
  o.normal_bits = normal_bits;
  o.uv_bits = uv_bits;
  return o;
}

Status decode_sequence(const std::vector<uint8_t>& bytes, EventLog* out, PsqHeader* header) {
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder dec;
  PSQ_RETURN_IF_ERROR(dec.open(&in));
  if (header) *header = dec.header();
  out->schema = dec.schema();
  SequenceEvent e;
  for (;;) {
    PSQ_RETURN_IF_ERROR(dec.next(&e));
    if (e.kind == SequenceEvent::Kind::kEnd) return Status();
    out->events.push_back(e);
  }
}

}  // namespace psq::test
