// SPDX-License-Identifier: Apache-2.0
// psq/indexed_mesh.h: the streaming indexed-mesh model.
//
// An indexed mesh is a stream of vertices (a position and property values)
// and triangles (three vertex indices and property values). Vertices are
// numbered 0, 1, 2, ... in the order a source yields them. Every producer of
// an indexed mesh is a MeshSource (pull: next()); every consumer is a
// MeshSink (push: begin, vertex, triangle, finish). Nothing here requires the
// whole mesh in memory: readers and writers of PLY and OBJ (tools/), the
// external sort and the converter (format/) are built on these interfaces.
//
// Property values of every type are carried as double, which holds every
// value of every PLY scalar type exactly (8- to 32-bit integers and 32- and
// 64-bit floats); the declared type is kept in the schema so that writers
// reproduce it.
#ifndef PSQ_INDEXED_MESH_H_
#define PSQ_INDEXED_MESH_H_

#include <cstdint>
#include <string>
#include <vector>

#include "psq/status.h"

namespace psq {

enum class ScalarType : uint8_t {
  kInt8 = 1,
  kUInt8 = 2,
  kInt16 = 3,
  kUInt16 = 4,
  kInt32 = 5,
  kUInt32 = 6,
  kFloat32 = 7,
  kFloat64 = 8,
};

// Size in bytes of one value of `t`.
int scalar_size(ScalarType t);
// The PLY name of `t` ("uchar", "float", ...).
const char* scalar_name(ScalarType t);
// True for kFloat32 and kFloat64.
bool scalar_is_float(ScalarType t);
// True when `v` is a value that type `t` represents exactly (in range, and
// integral for integer types, float-representable for kFloat32).
bool scalar_holds(ScalarType t, double v);

// One vertex or face property other than the position and the indices.
struct Property {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  bool is_list = false;                         // a list of values of `type`
  ScalarType count_type = ScalarType::kUInt8;   // type of the list's count

  bool operator==(const Property& o) const {
    return name == o.name && type == o.type && is_list == o.is_list &&
           (!is_list || count_type == o.count_type);
  }
};

// What a source promises about the stream it yields.
struct MeshSchema {
  static constexpr int64_t kUnknown = -1;

  ScalarType position_type = ScalarType::kFloat32;  // kFloat32 or kFloat64
  std::vector<Property> vertex_properties;  // besides x, y, z
  std::vector<Property> face_properties;    // per triangle, besides indices
  // Exact numbers of vertices and triangles the source will yield, or
  // kUnknown (a polygon file's triangle count, an OBJ read from a pipe).
  int64_t vertex_count = kUnknown;
  int64_t triangle_count = kUnknown;
  std::vector<std::string> comments;  // free text kept from the input header
  // The bounding box of all positions, when the source knows it before its
  // first vertex (the sequence builder, which spools the input first; a
  // quantized .psq). The .psq encoder places its quantization grid on it.
  bool has_bounds = false;
  double bounds_min[3] = {0, 0, 0};
  double bounds_max[3] = {0, 0, 0};
};

// Flattened property values of one element: for each property of the schema
// in order, one value if scalar, or the count followed by that many values if
// a list. PropertyReader walks them.
using PropertyValues = std::vector<double>;

// Number of doubles that the values of `props` take when every list is
// empty; the minimal size of a valid PropertyValues.
size_t min_value_count(const std::vector<Property>& props);

// Checks that `values` is a well-formed flattening for `props`: list counts
// are non-negative integers and the lengths add up. Returns false otherwise.
bool values_match(const std::vector<Property>& props, const PropertyValues& values);

struct MeshItem {
  enum class Kind { kVertex, kTriangle, kEnd };
  Kind kind = Kind::kEnd;
  double position[3] = {0, 0, 0};  // kVertex
  uint32_t index[3] = {0, 0, 0};   // kTriangle
  PropertyValues values;           // kVertex or kTriangle
};

// Counters a source keeps about what it had to interpret.
struct SourceReport {
  uint64_t polygons_triangulated = 0;  // faces of 4+ corners split into fans
  uint64_t strip_triangles = 0;        // triangles decoded from tristrips
  uint64_t skipped_elements = 0;       // elements of unknown kind skipped
  // One line each about what was interpreted or not carried, for the user
  // ("3 vertices split at texture seams", "element 'material' skipped").
  std::vector<std::string> notes;
};

class MeshSource {
 public:
  virtual ~MeshSource() = default;
  // The schema; valid after the source was opened successfully.
  virtual const MeshSchema& schema() const = 0;
  // Yields the next vertex or triangle, or Kind::kEnd once. Sources yield
  // every vertex before the first triangle unless the input itself puts
  // faces first (a PLY whose face element precedes its vertex element). Every triangle's
  // indices are < the number of vertices the mesh has (checked by the
  // source), every position is finite, and `values` matches the schema.
  // Errors are sticky: after one, every call returns the same error.
  virtual Status next(MeshItem* item) = 0;
  virtual const SourceReport& report() const = 0;
};

class MeshSink {
 public:
  virtual ~MeshSink() = default;
  // Called once before anything else.
  virtual Status begin(const MeshSchema& schema) = 0;
  virtual Status vertex(const double position[3], const PropertyValues& values) = 0;
  virtual Status triangle(const uint32_t index[3], const PropertyValues& values) = 0;
  // Called once after the last element. A sink writing an OutputFile writes
  // everything here but does not commit: its owner commits the file, so that
  // a failure anywhere in a pipeline leaves no output behind.
  virtual Status finish() = 0;
};

// Pulls everything from `source` into `sink`: begin, every element, finish.
// Returns the first error of either side.
Status pump(MeshSource& source, MeshSink& sink);

}  // namespace psq

#endif  // PSQ_INDEXED_MESH_H_
