// SPDX-License-Identifier: Apache-2.0
#include "psq/indexed_mesh.h"

#include <cmath>
#include <limits>

namespace psq {

int scalar_size(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8:
    case ScalarType::kUInt8: return 1;
    case ScalarType::kInt16:
    case ScalarType::kUInt16: return 2;
    case ScalarType::kInt32:
    case ScalarType::kUInt32:
    case ScalarType::kFloat32: return 4;
    case ScalarType::kFloat64: return 8;
  }
  return 0;
}

const char* scalar_name(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8: return "char";
    case ScalarType::kUInt8: return "uchar";
    case ScalarType::kInt16: return "short";
    case ScalarType::kUInt16: return "ushort";
    case ScalarType::kInt32: return "int";
    case ScalarType::kUInt32: return "uint";
    case ScalarType::kFloat32: return "float";
    case ScalarType::kFloat64: return "double";
  }
  return "?";
}

bool scalar_is_float(ScalarType t) {
  return t == ScalarType::kFloat32 || t == ScalarType::kFloat64;
}

bool scalar_holds(ScalarType t, double v) {
  auto in = [v](double lo, double hi) { return v >= lo && v <= hi && std::floor(v) == v; };
  switch (t) {
    case ScalarType::kInt8: return in(-128, 127);
    case ScalarType::kUInt8: return in(0, 255);
    case ScalarType::kInt16: return in(-32768, 32767);
    case ScalarType::kUInt16: return in(0, 65535);
    case ScalarType::kInt32: return in(-2147483648.0, 2147483647.0);
    case ScalarType::kUInt32: return in(0, 4294967295.0);
    case ScalarType::kFloat32: {
      if (std::isnan(v)) return true;
      volatile float f = static_cast<float>(v);  // volatile: see toolchain/README
      return static_cast<double>(f) == v;
    }
    case ScalarType::kFloat64: return true;
  }
  return false;
}

size_t min_value_count(const std::vector<Property>& props) { return props.size(); }

bool values_match(const std::vector<Property>& props, const PropertyValues& values) {
  size_t at = 0;
  for (const Property& p : props) {
    if (at >= values.size()) return false;
    if (p.is_list) {
      double count = values[at++];
      if (!(count >= 0) || std::floor(count) != count || count > values.size() - at) return false;
      at += static_cast<size_t>(count);
    } else {
      ++at;
    }
  }
  return at == values.size();
}

Status pump(MeshSource& source, MeshSink& sink) {
  PSQ_RETURN_IF_ERROR(sink.begin(source.schema()));
  MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(source.next(&item));
    switch (item.kind) {
      case MeshItem::Kind::kVertex:
        PSQ_RETURN_IF_ERROR(sink.vertex(item.position, item.values));
        break;
      case MeshItem::Kind::kTriangle:
        PSQ_RETURN_IF_ERROR(sink.triangle(item.index, item.values));
        break;
      case MeshItem::Kind::kEnd:
        return sink.finish();
    }
  }
}

}  // namespace psq
