// SPDX-License-Identifier: Apache-2.0
// Token parsing shared by the text mesh readers (OBJ, OFF, STL): locale-
// independent numbers through std::from_chars, and tokens quoted safely in
// error messages. Internal to tools/; not installed.
#ifndef PSQ_TOOLS_TEXT_PARSE_H_
#define PSQ_TOOLS_TEXT_PARSE_H_

#include <cstdint>
#include <string>
#include <string_view>

namespace psq::detail {

// A token for an error message: quoted, at most 32 characters, printable.
std::string quoted(std::string_view tok);

// Skips a leading '+' (std::from_chars takes none); false for "+", "++" or
// "+-" (malformed).
bool skip_plus(const char** b, const char* e);

enum class Parse { kOk, kMalformed, kOutOfRange };

// Parses a whole token as a float, rounding once from the decimal text.
// Values too small for float become 0 (or a denormal); values too large are
// out of range rather than silently infinite.
Parse parse_float(std::string_view tok, float* out);

// Parses a whole token as a decimal integer (a leading '+' allowed).
Parse parse_int(std::string_view tok, int64_t* out);

}  // namespace psq::detail

#endif  // PSQ_TOOLS_TEXT_PARSE_H_
