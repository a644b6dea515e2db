#include "progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace psq::cli {
namespace {

std::string human(double v, const char* unit) {
  char buf[64];
  if (v >= 1e9) std::snprintf(buf, sizeof buf, "%.2fG%s", v / 1e9, unit);
  else if (v >= 1e6) std::snprintf(buf, sizeof buf, "%.2fM%s", v / 1e6, unit);
  else if (v >= 1e3) std::snprintf(buf, sizeof buf, "%.1fk%s", v / 1e3, unit);
  else std::snprintf(buf, sizeof buf, "%.0f%s", v, unit);
  return buf;
}

}  // namespace

Progress::Progress(const InputStream* input, bool enabled)
    : input_(input), active_(enabled && ::isatty(STDERR_FILENO) == 1) {
  start_ = last_ = std::chrono::steady_clock::now();
}

Progress::~Progress() {
  if (drawn_) std::fputs("\r\033[K", stderr);
}

double Progress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::draw(bool force) {
  auto now = std::chrono::steady_clock::now();
  if (!force && now - last_ < std::chrono::milliseconds(100)) return;  // at most 10 a second
  last_ = now;
  const double t = std::chrono::duration<double>(now - start_).count();
  // Triangles read, or (when nothing counts input triangles, as for a .psq
  // decoded into a sink) triangles written.
  const uint64_t count = triangles_ ? triangles_ : written_;
  const double rate = t > 0 ? static_cast<double>(count) / t : 0;
  std::string line = "psq: " + human(static_cast<double>(count), " triangles") + ", " + human(rate, " triangles/s");
  const uint64_t at = input_ ? input_->offset() : 0;
  if (input_ && input_->size() > 0) {
    const double frac = static_cast<double>(at) / static_cast<double>(input_->size());
    char buf[96];
    if (frac > 0.001 && frac < 1) {
      std::snprintf(buf, sizeof buf, "%5.1f%% of input, ", 100 * frac);
      line = "psq: " + std::string(buf) + line.substr(5);
      std::snprintf(buf, sizeof buf, ", %.0f s left", t / frac - t);
      line += buf;
    } else if (frac >= 1 && written_ > 0 && triangles_ > 0 && written_ < triangles_) {
      // Input read (spooled): now the share of its triangles written.
      const double w = static_cast<double>(written_) / static_cast<double>(triangles_);
      const double wrate = t > 0 ? static_cast<double>(written_) / t : 0;
      std::snprintf(buf, sizeof buf, "%5.1f%% written, ", 100 * std::min(w, 1.0));
      line = "psq: " + std::string(buf) + human(static_cast<double>(written_), " triangles") + ", " +
             human(wrate, " triangles/s");
    }
  } else if (input_) {
    line += ", " + human(static_cast<double>(at), "B") + " read";
  }
  std::fprintf(stderr, "\r\033[K%s", line.c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void Progress::finish(const std::string& in, const std::string& out, const std::string& summary) {
  if (!active_) return;
  if (drawn_) std::fputs("\r\033[K", stderr);
  drawn_ = false;
  std::fprintf(stderr, "psq: %s -> %s: %s, %.1f s\n", in.c_str(), out.c_str(), summary.c_str(), seconds());
}

}  // namespace psq::cli
