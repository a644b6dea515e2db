// SPDX-License-Identifier: Apache-2.0
// codec/src/attributes.h: vertex attributes coded like positions
// (spec/psq-format.md 8.3, 8.4): texture coordinates (a grid) and
// colours (exact bytes) predicted across the gate when their vertex comes;
// normals (octahedral) when their vertex settles, predicted from the
// triangles around it, since a streaming decoder knows one of them when
// the vertex comes; coded in a section of each chunk, by the range coder
// with the adaptive back-end and by rANS with the rANS back-end (13.8.4).
// The coder sees a record as its events: the new vertices in order of
// introduction and the triangle with its vertex and edge slots and the
// corners it finalizes, so that the record loops of the encoder and the
// decoder share it. Corner attributes (8.5), in corners.cpp, are coded
// after them in the same section.
#ifndef PSQ_CODEC_ATTRIBUTES_H_
#define PSQ_CODEC_ATTRIBUTES_H_

#include <algorithm>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "coding.h"
#include "rans.h"
#include "psq/psq_codec.h"
#include "psq/status.h"

namespace psq {
namespace codec {

constexpr int kMaxAttributeComponents = 9;  // a normal, a texture coordinate and a colour with alpha
constexpr uint32_t kMaxAttributeBytes = 1u << 26;  // the attribute section of one chunk (spec 4.4)
// A normal waits for its vertex to be finalized at most this many records
// (spec 8.4), which bounds what a decoder holds back.
constexpr uint64_t kMaxNormalWait = 1u << 12;
// The distinct values of a corner attribute a vertex keeps for its corners
// to refer to (spec 8.5); a new one beyond them drops the least recent.
constexpr int kMaxWedges = 8;
// The wedge symbol that says "a new value" (spec 8.5).
constexpr uint32_t kNewWedge = kMaxWedges;

// The attributes the encoder codes for a schema: the first normal, texture
// coordinate and colour found by their names (spec 8.3). Normals and
// texture coordinates only with non-zero bits.
// Per corner (8.5): the face properties corner_normals and corner_uv, float
// or double lists.
std::vector<CodedAttribute> recognize_attributes(const MeshSchema& schema, int normal_bits, int uv_bits);

// Spec 4.2: a stream keeps the triangles' rotation when a face property is
// not a corner attribute (whose values follow their corners).
bool rotation_kept(const MeshSchema& schema, const std::vector<CodedAttribute>& attrs);

// Checks a header's attribute table against its properties (spec 4.2); an
// empty string when it is valid, else what is wrong.
std::string attribute_table_error(const MeshSchema& schema, const std::vector<CodedAttribute>& attrs);

// What the coder needs of one record (spec 8.3): the new vertices in order
// of introduction; for a triangle, its corners' dense indices and vertex
// slots and its edges' slots, in any rotation (edge k joins corner k to
// corner k + 1), which corners are new and which edges enter.
struct AttributeRecord {
  int nnew = 0;
  uint32_t index[3] = {0, 0, 0};
  bool triangle = false;
  uint32_t v[3] = {0, 0, 0}, c[3] = {0, 0, 0}, e[3] = {0, 0, 0};
  uint8_t new_mask = 0, entering_mask = 0, final_mask = 0;
  // The end of a chunk: every normal still waiting is coded (spec 8.4).
  bool flush = false;
  // The corners' coded coordinates in a quantized stream (spec 7.1: texture
  // coordinates are predicted from the new triangle's shape), else null.
  const int64_t* pos[3] = {nullptr, nullptr, nullptr};
  // A triangle's corner attribute values (spec 8.5), corner_dims() a
  // corner, in the corner order above, and the number the decoder gives its
  // event (a corner normal still to come names it).
  int32_t* corners = nullptr;
  uint64_t event = 0;
};

// The attribute section of a chunk with the rANS back-end (spec 13.8.4):
// the residuals' length symbols with static tables and rANS, their low
// bits and signs raw.
struct FastAttributeWriter {
  std::vector<RansSymbol> symbols;
  std::vector<uint64_t> counts;  // [table][symbol], this chunk's
  RawWriter raw;
  // Roughly the section's size so far (the encoder's chunk target).
  size_t size_estimate() const { return static_cast<size_t>(raw.bits() / 8) + symbols.size(); }
};
struct FastAttributeReader {
  std::vector<RansTable> tables;
  std::unique_ptr<RansDecoder> rans;
  std::unique_ptr<RawReader> raw;
};

class AttributeCoder {
 public:
  AttributeCoder(const MeshSchema& schema, const std::vector<CodedAttribute>& attrs);
  bool empty() const { return dims_ == 0 && corner_.empty(); }
  int dims() const { return dims_; }
  // The vertex and face properties left to the property columns (spec 8.1).
  const std::vector<Property>& column_properties() const { return columns_; }
  const std::vector<Property>& face_column_properties() const { return face_columns_; }
  // Corner attributes (spec 8.5): coded values a corner.
  int corner_dims() const { return 2 * static_cast<int>(corner_.size()); }
  // Encoder: a face's values split into its column values and its corners'
  // quantized values cq[3 * corner_dims()], corner by corner; kBadValue for
  // a list of another length or a value the attribute cannot hold.
  Status split_face(const PropertyValues& in, uint64_t face, PropertyValues* columns, int32_t* cq) const;
  // Decoder: the face's values in schema order.
  void merge_face(const PropertyValues& columns, const int32_t* cq, PropertyValues* out) const;

  // Encoder: a vertex's values (matching the schema) split into the
  // column values and the quantized attribute values q[dims()]. kBadValue
  // for a normal that is not finite or zero, or a texture coordinate
  // beyond the grid.
  Status split(const PropertyValues& in, uint64_t vertex, PropertyValues* columns, int32_t* q) const;
  // Decoder: the values in schema order from the column values and q.
  void merge(const PropertyValues& columns, const int32_t* q, PropertyValues* out) const;

  // The adaptive back-end (spec 8.3), with the range coder.
  // Codes one record; `q` holds r.nnew vertices' values, dims() each.
  void encode(Encoder& enc, const AttributeRecord& r, const int32_t* q);
  // Decodes one record into q; nullptr, or why the stream is corrupt.
  const char* decode(Decoder& dec, const AttributeRecord& r, int32_t* q);

  // The rANS back-end (spec 13.8.4): the same predictions and contexts,
  // the residuals as length symbols of static tables.
  void encode_fast(FastAttributeWriter& w, const AttributeRecord& r, const int32_t* q);
  // Appends a chunk's section and starts the next.
  void finish_fast(FastAttributeWriter& w, std::vector<uint8_t>* out) const;
  // Reads a chunk's tables; nullptr, or why the section is corrupt.
  const char* open_fast(FastAttributeReader& rd, const uint8_t* data, size_t size) const;
  const char* decode_fast(FastAttributeReader& rd, const AttributeRecord& r, int32_t* q);
  // The table of a residual (spec 13.8.4).
  // Segments (spec 4.6): the state that carries over, by slot, and the
  // adaptive models' fresh start.
  const int32_t* last() const { return last_; }
  void set_last(const int32_t* v) { std::copy(v, v + dims_, last_); }
  int32_t* vertex_state(uint32_t slot) { return vertex_values(slot); }
  int32_t* edge_state(uint32_t slot) { return edge_values(slot); }
  // Whether v is a value component d can hold.
  bool in_range(int d, int64_t v) const { return v >= comp_[d].lo && v <= comp_[d].hi; }
  void restart_models();
  // Normals are coded when their vertex settles (spec 8.4): the vertices
  // whose normals the last record coded, with their values.
  bool late() const { return late_d_ >= 0 || late_corners_; }
  bool late_vertices() const { return late_d_ >= 0; }
  struct Settled {
    uint32_t index;
    int32_t q[kMaxAttributeComponents];
  };
  const std::vector<Settled>& settled() const { return settled_; }
  // Corner normals are coded when their wedge settles (spec 8.5): the
  // last record's triangle's corners that still wait for one, and the
  // corners of earlier triangles (by their events) whose normals came.
  int pending_corners() const { return pending_corners_; }
  struct SettledCorner {
    uint64_t event;
    int corner, attribute;
    int32_t q[2];
  };
  const std::vector<SettledCorner>& settled_corners() const { return settled_corners_; }
  // Decoder: a settled corner's normal into its triangle's face values.
  void patch_face(PropertyValues* values, const SettledCorner& s) const;
  // Spec 8.4: a record's triangle's area vector, exact in integers (the
  // same for every rotation of its corners) and then binary64; zero in a
  // lossless stream.
  static void area_vector(const AttributeRecord& r, double n[3]);
  int fast_table(int kind, int d, int ctx) const { return (kind * dims_ + d) * 3 + (ctx < 4 ? 0 : ctx < 8 ? 1 : 2); }
  int fast_tables() const { return 6 * dims_ + 33 * static_cast<int>(corner_.size()); }

 private:
  struct Component {
    int bits = 0;         // a normal's bits, else 0
    int64_t mod = 0;      // values modulo this (normals, colours), 0: none (texture coordinates)
    int64_t lo = 0, hi = 0;  // valid values
    bool parallelogram = false;  // predicted across the gate, else the mean of its ends
    bool first = false;   // the first component of its attribute
    bool late = false;    // coded when its vertex settles (a normal), else at introduction
  };
  // A vertex slot's normal waiting to be coded (spec 8.4): the sum of its
  // triangles' area vectors so far.
  struct Ring {
    double n[3] = {0, 0, 0};
    uint32_t index = 0;
    bool waiting = false;
  };
  struct Waiting {
    uint32_t slot, index;
    uint64_t record;
  };
  // How a record is coded (attributes.cpp): residuals by a model
  // (adaptive back-end) or a table (rANS), and corners' wedge symbols.
  struct Coding {
    virtual ~Coding() = default;
    const char* why = nullptr;
    virtual bool residual(int table, ResidualModel& m, const Component& c, int64_t pred, int32_t* x, int* length) = 0;
    virtual bool symbol(int table, SymbolModel& m, uint32_t* s) = 0;
  };
  struct AdaptiveOut;
  struct AdaptiveIn;
  struct FastOut;
  struct FastIn;
  template <class C>
  const char* code_record(const AttributeRecord& r, int32_t* q, C& code);
  template <class Code>
  bool ring_step(const AttributeRecord& r, Code& code);
  template <class Code>
  bool settle(int kind, Ring* ring, uint32_t index, int32_t* x, Code& code);
  template <class Code>
  bool walk(const AttributeRecord& r, int32_t* q, Code&& code);
  // A corner attribute (spec 8.5): its values' components, its models, the
  // value coded before and the texture's orientation seen last.
  struct Corner {
    CodedAttribute::Kind kind;
    int bits;
    Component comp[2];
    std::vector<ResidualModel> models;  // [rule: 0-2 at once, 3-4 settled][component][length context]
    SymbolModel wedge[3] = {SymbolModel(4), SymbolModel(4), SymbolModel(4)};  // by the vertex's wedges: 1, 2, more
    int32_t last[2];
    int orientation;
  };
  // The values a vertex slot keeps for one corner attribute, most recent
  // first. A normal that waits for its fan (spec 8.5) has a Waiter: its
  // number, its triangles' area vectors and the corners that took it.
  struct Wedge {
    int32_t v[2];
    uint32_t wait;  // 0, or 1 + its entry in waiters_
  };
  struct Wedges {
    int n = 0;
    Wedge w[kMaxWedges];
  };
  struct Waiter {
    uint64_t serial;
    double n[3];
    std::vector<uint64_t> refs;  // event * 4 + corner
  };
  struct CornerWaiting {
    uint32_t slot;
    uint32_t attribute;
    uint64_t serial, record;
  };
  // A record's corner attributes (corners.cpp), after its vertices'
  // values: nullptr, or why the stream is corrupt.
  const char* code_corners(const AttributeRecord& r, Coding& code);
  // The corners' values of a triangle (corners.cpp). `code` codes wedge
  // symbols, code.symbol(table, model, &s), and residuals,
  // code.residual(table, model, component, pred, &x, &length).
  bool corner_walk(const AttributeRecord& r, Coding& code);
  bool corner_settle(Coding& code, size_t ai, Wedge& w, int kind);
  bool corners_due(const AttributeRecord& r, Coding& code);
  void predict_texcoord(const AttributeRecord& r, const Corner& a, int j, const bool* known, int32_t (*x)[2],
                        int* rule, int64_t* pred, int* extent) const;
  void release(Wedge& w);
  Wedges& wedges(uint32_t slot, size_t a);
  int corner_table(size_t a, int rule, int d, int ctx) const {
    return 6 * dims_ + ((static_cast<int>(a) * 5 + rule) * 2 + d) * 3 + (ctx < 4 ? 0 : ctx < 8 ? 1 : 2);
  }
  int wedge_table(size_t a, int ctx) const {
    return 6 * dims_ + 30 * static_cast<int>(corner_.size()) + static_cast<int>(a) * 3 + ctx;
  }
  // Component `c`'s value from its prediction and decoded residual (spec
  // 8.3): modulo its range for a wrapping component, within its grid for a
  // texture coordinate; nullptr, or why the residual cannot be one.
  static const char* component_value(const Component& c, int64_t pred, int64_t res, int32_t* out);
  // The residual that codes `value` against `pred`: for a wrapping
  // component, the one of least magnitude modulo its range (spec 8.3).
  static int64_t component_residual(const Component& c, int64_t pred, int64_t value);
  void predict_texcoord(const AttributeRecord& r, int j, int d, const int32_t* a, const int32_t* b, const int32_t* o,
                        int64_t* pred) const;
  // Spec 8.3, 8.5: where corner j of a quantized stream's triangle lies
  // beside the edge from corner j + 1 to j + 2: its foot t on the edge and
  // its distance h from it, in edge lengths; false for an edge of no
  // length. texture_point() carries that to the edge from a to b in the
  // texture, at signed distance w, rounded to the grid (none beyond 4e9).
  static bool beside_edge(const AttributeRecord& r, int j, double* t, double* h);
  static void texture_point(const int32_t* a, const int32_t* b, double t, double w, const Component& c, int64_t* pred);
  int32_t* vertex_values(uint32_t slot) { return slot_values(&vattr_, slot); }
  int32_t* edge_values(uint32_t slot) { return slot_values(&eattr_, slot); }
  // Inline, as a record takes several; grow() only for a slot beyond the
  // array, which holds whole slots (dims_ values each).
  int32_t* slot_values(std::vector<int32_t>* a, uint32_t slot) {
    const size_t at = static_cast<size_t>(slot) * static_cast<size_t>(dims_);
    return at < a->size() ? a->data() + at : grow(a, slot);
  }
  int32_t* grow(std::vector<int32_t>* a, uint32_t slot);
  ResidualModel& model(int kind, int d, int ctx) {
    return models_[(static_cast<size_t>(kind) * static_cast<size_t>(dims_) + static_cast<size_t>(d)) * kLengthContexts +
                   static_cast<size_t>(ctx)];
  }

  std::vector<CodedAttribute> attrs_;
  std::vector<Property> vertex_, columns_, face_, face_columns_;
  std::vector<Corner> corner_;
  std::vector<Wedges> wedges_;  // [vertex slot][corner attribute]
  std::vector<int> role_;  // per vertex property: its component, or -1 for a column
  std::vector<int> face_role_;  // per face property: its corner attribute, or -1 for a column
  int dims_ = 0;  // coded values a vertex: a normal's two, a texture coordinate's two, a colour's 3 or 4
  Component comp_[kMaxAttributeComponents];
  std::vector<ResidualModel> models_;  // [kind: gate, other][component][length context]
  std::vector<int32_t> vattr_, eattr_;  // by vertex slot, by edge slot (its opposite vertex's)
  int32_t last_[kMaxAttributeComponents] = {};
  int late_d_ = -1;  // the normal's first coded value, or -1
  std::vector<Ring> rings_;  // by vertex slot
  std::deque<Waiting> waiting_;  // in order of introduction
  uint64_t records_ = 0;
  std::vector<Settled> settled_;
  bool late_corners_ = false;  // a corner normal
  int pending_corners_ = 0;
  uint64_t serial_ = 0;
  std::deque<CornerWaiting> corner_waiting_;  // in order of creation
  std::vector<Waiter> waiters_;
  std::vector<uint32_t> free_waiters_;
  std::vector<SettledCorner> settled_corners_;
};

// Inline: every triangle takes it, for 8.4 and for 8.5.
inline void AttributeCoder::area_vector(const AttributeRecord& r, double n[3]) {
  n[0] = n[1] = n[2] = 0;
  if (r.pos[0] == nullptr) return;
  // Coordinates on a grid of at most 31 bits (spec 4.2): the products
  // stay below 2^62 and their differences below 2^63.
  int64_t e[3], f[3];
  for (int i = 0; i < 3; ++i) {
    e[i] = r.pos[1][i] - r.pos[0][i];
    f[i] = r.pos[2][i] - r.pos[0][i];
  }
  n[0] = static_cast<double>(e[1] * f[2] - e[2] * f[1]);
  n[1] = static_cast<double>(e[2] * f[0] - e[0] * f[2]);
  n[2] = static_cast<double>(e[0] * f[1] - e[1] * f[0]);
}

// The length context of component d (spec 8.3): the predicting values'
// spread for an attribute's first component; for the others, the mean of
// that spread and the longest residual of the attribute's earlier
// components when predicted across the gate (kind 0), else that longest
// residual alone.
inline int attribute_context(int kind, bool first, int extent, int longest) {
  const int c = first ? extent : kind == 0 ? (extent + longest + 1) / 2 : longest;
  return std::min(c, kLengthContexts - 1);
}

// Normals on the octahedron (spec 8.3): `c` = 2^(bits - 1) - 1.
void octahedral_decode(int32_t s, int32_t t, int32_t c, double out[3]);
// The grid point whose decoded normal is nearest to n; a zero normal is
// (0, 0, 1). False when n is not finite.
bool octahedral_encode(const double n[3], int32_t c, int32_t* s, int32_t* t);
// The grid point of direction n by rounding (spec 8.3, the prediction of a
// normal): false for the zero vector.
bool octahedral_round(const double n[3], int32_t c, int64_t* s, int64_t* t);

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_ATTRIBUTES_H_
