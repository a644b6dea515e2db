// SPDX-License-Identifier: Apache-2.0
// DumpWriter (sequence_dump.h): the "psq-dump 1" text form of a
// processing sequence, specified in spec/psq-dump.md.
#include "sequence_dump.h"

#include <cinttypes>
#include <cstdio>

namespace psq {

DumpWriter::DumpWriter(OutputFile* out) : out_(out) {}

Status DumpWriter::begin(const MeshSchema& schema) {
  schema_ = schema;
  return out_->write("psq-dump 1\n");
}

void DumpWriter::append_number(double v, ScalarType t) {
  char buf[40];
  int n;
  if (t == ScalarType::kFloat32) {
    n = std::snprintf(buf, sizeof buf, "%.9g", v);
  } else if (t == ScalarType::kFloat64) {
    n = std::snprintf(buf, sizeof buf, "%.17g", v);
  } else {
    n = std::snprintf(buf, sizeof buf, "%" PRId64, static_cast<int64_t>(v));
  }
  line_.append(buf, static_cast<size_t>(n));
}

void DumpWriter::append_values(const std::vector<Property>& props, const PropertyValues& values) {
  size_t at = 0;
  for (const Property& p : props) {
    if (at >= values.size()) return;  // sources guarantee the shape; stay in bounds regardless
    line_ += ' ';
    line_ += p.name;
    line_ += '=';
    if (!p.is_list) {
      append_number(values[at++], p.type);
      continue;
    }
    size_t count = static_cast<size_t>(values[at++]);
    for (size_t k = 0; k < count && at < values.size(); ++k) {
      if (k) line_ += ',';
      append_number(values[at++], p.type);
    }
  }
}

Status DumpWriter::vertex(const SequenceVertex& v) {
  line_ = "v";
  for (int k = 0; k < 3; ++k) {
    line_ += ' ';
    append_number(v.position[k], schema_.position_type == ScalarType::kFloat64 ? ScalarType::kFloat64 : ScalarType::kFloat32);
  }
  if (v.reappears != kNoVertex) line_ += " ~" + std::to_string(v.reappears);
  append_values(schema_.vertex_properties, v.values);
  line_ += '\n';
  return out_->write(line_);
}

Status DumpWriter::triangle(const SequenceTriangle& t) {
  char buf[96];
  int n = std::snprintf(buf, sizeof buf, "t %u %u %u %s %u", t.v[0], t.v[1], t.v[2], op_name(t.op),
                        static_cast<unsigned>(t.border_mask));
  line_.assign(buf, static_cast<size_t>(n));
  append_values(schema_.face_properties, t.values);
  line_ += '\n';
  return out_->write(line_);
}

Status DumpWriter::finalize(uint32_t index) {
  char buf[24];
  int n = std::snprintf(buf, sizeof buf, "x %u\n", index);
  return out_->write(buf, static_cast<size_t>(n));
}

Status DumpWriter::finish() { return Status(); }

}  // namespace psq
