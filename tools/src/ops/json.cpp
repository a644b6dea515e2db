// SPDX-License-Identifier: Apache-2.0
// JSON text as psq writes it (RFC 8259); see json.h.
#include "json.h"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace psq::detail {

std::string json_escape(const std::string& s) {
  std::string out;
  for (unsigned char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  return out;
}

std::string json_string(const std::string& s) { return "\"" + json_escape(s) + "\""; }

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string json_strings(const std::vector<std::string>& items) {
  std::string o = "[";
  for (size_t i = 0; i < items.size(); ++i) o += (i ? ", " : "") + json_string(items[i]);
  return o + "]";
}

std::string json_properties(const std::vector<Property>& props) {
  std::string s = "[";
  for (size_t i = 0; i < props.size(); ++i) {
    const Property& p = props[i];
    if (i) s += ", ";
    s += "{\"name\": " + json_string(p.name) + ", \"type\": \"" + scalar_name(p.type) + "\"";
    if (p.is_list) s += std::string(", \"list\": true, \"count_type\": \"") + scalar_name(p.count_type) + "\"";
    s += "}";
  }
  return s + "]";
}

std::string json_box(const double lo[3], const double hi[3]) {
  return "{\"min\": [" + json_number(lo[0]) + ", " + json_number(lo[1]) + ", " + json_number(lo[2]) + "], \"max\": [" +
         json_number(hi[0]) + ", " + json_number(hi[1]) + ", " + json_number(hi[2]) + "]}";
}

}  // namespace psq::detail
