// SPDX-License-Identifier: Apache-2.0
#include "progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
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

void RateMeter::reset(double t, double count, double fraction) {
  t_ = t;
  count_ = count;
  fraction_ = fraction;
  done_ = fraction_done_ = time_ = 0;
}

void RateMeter::update(double t, double count, double fraction) {
  const double dt = t - t_;
  if (dt <= 0) return;
  // What was done and the time it took, each older second weighing less.
  const double decay = std::exp(-dt / tau_);
  done_ = done_ * decay + (count - count_);
  time_ = time_ * decay + dt;
  if (fraction >= 0 && fraction_ >= 0) fraction_done_ = fraction_done_ * decay + (fraction - fraction_);
  else fraction_done_ = 0;
  t_ = t;
  count_ = count;
  fraction_ = fraction;
}

double RateMeter::rate() const { return time_ > 0 ? done_ / time_ : -1; }

double RateMeter::seconds_left() const {
  if (time_ <= 0 || fraction_ < 0 || fraction_done_ <= 0) return -1;
  return std::max(0.0, (1 - std::min(fraction_, 1.0)) * time_ / fraction_done_);
}

std::string format_duration(double seconds) {
  const long long s = std::llround(std::max(0.0, seconds));
  char buf[64];
  if (s < 60) std::snprintf(buf, sizeof buf, "%lld s", s);
  else if (s < 3600) std::snprintf(buf, sizeof buf, "%lld min %02lld s", s / 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%lld h %02lld min", s / 3600, s / 60 % 60);
  return buf;
}

std::string progress_line(double count, double rate, double fraction, const char* what, double seconds_left,
                          int64_t bytes_read) {
  std::string line = "psq: ";
  if (fraction >= 0) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%5.1f%% %s, ", 100 * std::min(fraction, 1.0), what);
    line += buf;
  }
  line += human(count, " triangles");
  if (rate >= 0) line += ", " + human(rate, " triangles/s");
  if (seconds_left >= 0) line += ", " + format_duration(seconds_left) + " left";
  if (bytes_read >= 0) line += ", " + human(static_cast<double>(bytes_read), "B") + " read";
  return line;
}

Progress::Progress(const InputStream* input, bool enabled)
    : input_(input), active_(enabled && ::isatty(STDERR_FILENO) == 1) {
  start_ = last_ = std::chrono::steady_clock::now();
  const bool sized = input_ && input_->size() > 0;
  phase_ = sized ? Phase::kReading : Phase::kUnknown;
  meter_.reset(0, 0, sized ? static_cast<double>(input_->offset()) / static_cast<double>(input_->size()) : -1);
}

Progress::~Progress() { clear(); }

double Progress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::draw(bool force) {
  auto now = std::chrono::steady_clock::now();
  if (!force && now - last_ < std::chrono::milliseconds(100)) return;  // at most 10 a second
  last_ = now;
  const double t = std::chrono::duration<double>(now - start_).count();
  const uint64_t at = input_ ? input_->offset() : 0;
  const int64_t size = input_ ? input_->size() : -1;
  // Triangles read, or (when nothing counts input triangles, as for a .psq
  // decoded into a sink) triangles written.
  double count = static_cast<double>(triangles_ ? triangles_ : written_);
  double fraction = -1;
  const char* what = "";
  Phase phase = Phase::kUnknown;
  if (size > 0 && at < static_cast<uint64_t>(size)) {
    phase = Phase::kReading;
    fraction = static_cast<double>(at) / static_cast<double>(size);
    what = "of input";
  } else if (size > 0 && written_ > 0 && triangles_ > 0 && written_ < triangles_) {
    // Input read (spooled): now the share of its triangles written.
    phase = Phase::kWriting;
    count = static_cast<double>(written_);
    fraction = static_cast<double>(written_) / static_cast<double>(triangles_);
    what = "written";
  }
  // A new phase has a rate of its own: measure it afresh.
  if (phase != phase_) {
    phase_ = phase;
    meter_.reset(t, count, fraction);
  } else {
    meter_.update(t, count, fraction);
  }
  const std::string line =
      progress_line(count, meter_.rate(), fraction, what, meter_.seconds_left(), input_ && size < 0 ? static_cast<int64_t>(at) : -1);
  std::fprintf(stderr, "\r\033[K%s", line.c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void Progress::clear() {
  if (!drawn_) return;
  std::fputs("\r\033[K", stderr);
  std::fflush(stderr);
  drawn_ = false;
}

void Progress::finish(const std::string& in, const std::string& out, const std::string& summary) {
  if (!active_) return;
  clear();
  std::fprintf(stderr, "psq: %s -> %s: %s, %.1f s\n", in.c_str(), out.c_str(), summary.c_str(), seconds());
}

}  // namespace psq::cli
