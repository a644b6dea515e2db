// SPDX-License-Identifier: Apache-2.0
// tools/src/ops: the operations that the psq command (tools/cli) and the
// Python module (python/src) both offer, written once: the report of psq
// info, the distance report, the simplification runs and the plumbing of
// a pipeline's input and output. Internal (not installed): the command and
// the module are its only callers, and what they print is documented with
// them (psq --help, python/README.md).
//
// This file: JSON text as psq writes it for --json.
#ifndef PSQ_TOOLS_OPS_JSON_H_
#define PSQ_TOOLS_OPS_JSON_H_

#include <cstdint>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"

namespace psq::detail {

// Escapes `s` for a JSON string literal (without the quotes). Bytes that
// are not UTF-8 pass through unchanged.
std::string json_escape(const std::string& s);
// `s` as a JSON string literal, quotes included.
std::string json_string(const std::string& s);
// Formats a double so that it reads back exactly; "null" for a NaN or an
// infinity (JSON has neither).
std::string json_number(double v);
// An array of strings: ["a", "b"].
std::string json_strings(const std::vector<std::string>& items);
// The properties of a schema: [{"name": ..., "type": ...}, ...], lists
// with "list": true and their "count_type".
std::string json_properties(const std::vector<Property>& props);
// A bounding box: {"min": [x, y, z], "max": [x, y, z]}.
std::string json_box(const double lo[3], const double hi[3]);

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_JSON_H_
