// SPDX-License-Identifier: Apache-2.0
// Token parsing shared by the text mesh readers (text_parse.h).
#include "text_parse.h"

#include <charconv>
#include <cmath>
#include <system_error>

namespace psq::detail {

std::string quoted(std::string_view tok) {
  constexpr size_t kMaxShown = 32;
  std::string s = "'";
  for (size_t i = 0; i < tok.size() && i < kMaxShown; ++i) {
    unsigned char c = static_cast<unsigned char>(tok[i]);
    s += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (tok.size() > kMaxShown) s += "...";
  s += "'";
  return s;
}

bool skip_plus(const char** b, const char* e) {
  if (*b != e && **b == '+') {
    ++*b;
    if (*b == e || **b == '+' || **b == '-') return false;
  }
  return true;
}

Parse parse_float(std::string_view tok, float* out) {
  const char* b = tok.data();
  const char* e = b + tok.size();
  if (!skip_plus(&b, e)) return Parse::kMalformed;
  float f = 0;
  auto r = std::from_chars(b, e, f);
  if (r.ptr != e) return Parse::kMalformed;
  if (r.ec == std::errc()) {
    *out = f;
    return Parse::kOk;
  }
  if (r.ec != std::errc::result_out_of_range) return Parse::kMalformed;
  // Tell underflow from overflow, which from_chars reports alike.
  double d = 0;
  auto rd = std::from_chars(b, e, d);
  if (rd.ec == std::errc()) {
    if (std::fabs(d) < 1.0) {
      *out = static_cast<float>(d);
      return Parse::kOk;
    }
    return Parse::kOutOfRange;
  }
  for (const char* p = b; p + 1 < e; ++p) {
    if ((*p == 'e' || *p == 'E') && p[1] == '-') {
      *out = *b == '-' ? -0.0f : 0.0f;
      return Parse::kOk;
    }
  }
  return Parse::kOutOfRange;
}

Parse parse_int(std::string_view tok, int64_t* out) {
  const char* b = tok.data();
  const char* e = b + tok.size();
  if (!skip_plus(&b, e)) return Parse::kMalformed;
  auto r = std::from_chars(b, e, *out);
  if (r.ec == std::errc::result_out_of_range && r.ptr == e) return Parse::kOutOfRange;
  if (r.ec != std::errc() || r.ptr != e) return Parse::kMalformed;
  return Parse::kOk;
}

}  // namespace psq::detail
