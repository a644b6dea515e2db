// SPDX-License-Identifier: Apache-2.0
// format/src/sequence_dump.h: the text dump of a processing sequence (spec/,
// appendix "psq-dump 1"), one event per line:
//
//   psq-dump 1
//   v X Y Z [NAME=VALUE ...]      a new vertex; it takes the next index
//   v X Y Z ~K [NAME=VALUE ...]   a new vertex that re-appears vertex K
//   t A B C OP M [NAME=VALUE ...] a triangle: OP in start|add|join|fill|end,
//                                 M the border mask (bit 0 edge A-B, bit 1
//                                 B-C, bit 2 C-A)
//   x A                           vertex A is finalized
//
// Float values print with %.9g and doubles with %.17g, so they read back
// bit-exact; integers print as integers; a list prints its values separated
// by commas.
#ifndef PSQ_FORMAT_SEQUENCE_DUMP_H_
#define PSQ_FORMAT_SEQUENCE_DUMP_H_

#include <string>

#include "psq/io.h"
#include "psq/sequence.h"

namespace psq {

class DumpWriter : public SequenceSink {
 public:
  // `out` must be open and outlive the writer; the caller commits it.
  explicit DumpWriter(OutputFile* out);

  Status begin(const MeshSchema& schema) override;
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  Status finish() override;

 private:
  void append_values(const std::vector<Property>& props, const PropertyValues& values);
  void append_number(double v, ScalarType t);

  OutputFile* out_;
  MeshSchema schema_;
  std::string line_;
};

}  // namespace psq

#endif  // PSQ_FORMAT_SEQUENCE_DUMP_H_
