// SPDX-License-Identifier: Apache-2.0
#include "cli_util.h"

#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <charconv>
#include <cctype>
#include <cmath>
#include <csignal>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "psq/io.h"

namespace psq::cli {

int report_error(const std::string& file, const Status& status) {
  if (status.code() == ErrorCode::kIo && output_pipe_closed()) return kExitBrokenPipe;
  std::string where = file.empty() ? "" : (file == "-" ? "<stdin>" : file) + ": ";
  std::fprintf(stderr, "psq: error: %s%s\n", where.c_str(), status.to_string().c_str());
  return status.code() == ErrorCode::kUsage ? kExitUsage : kExitFailure;
}

int report_pipeline_error(const std::string& in, const std::string& out, const Status& status) {
  return report_error(detail::error_is_about_output(status) ? out : in, status);
}

int usage_error(const std::string& command, const std::string& message) {
  std::fprintf(stderr, "psq: error: %s\n", message.c_str());
  std::fprintf(stderr, "Try 'psq %s--help' for more information.\n", command.empty() ? "" : (command + " ").c_str());
  return kExitUsage;
}

void warn(const std::string& file, const std::string& message) {
  std::fprintf(stderr, "psq: warning: %s: %s\n", file == "-" ? "<stdin>" : file.c_str(), message.c_str());
}

void note(const std::string& file, const std::string& message) {
  std::fprintf(stderr, "psq: note: %s: %s\n", file == "-" ? "<stdin>" : file.c_str(), message.c_str());
}

Args::Args(int argc, char** argv, int first) {
  for (int i = first; i < argc; ++i) args_.emplace_back(argv[i]);
  used_.assign(args_.size(), false);
}

bool Args::options_ended_at(size_t i) const {
  for (size_t k = 0; k < i; ++k) {
    if (args_[k] == "--") return true;
  }
  return false;
}

bool Args::flag(const std::string& name, const std::string& alias) {
  bool found = false;
  for (size_t i = 0; i < args_.size(); ++i) {
    if (used_[i] || options_ended_at(i)) continue;
    if (args_[i] == name || (!alias.empty() && args_[i] == alias)) {
      used_[i] = true;
      found = true;
    }
  }
  return found;
}

std::string Args::option(const std::string& name, const std::string& fallback) {
  std::string value = fallback;
  for (size_t i = 0; i < args_.size(); ++i) {
    if (used_[i] || options_ended_at(i)) continue;
    if (args_[i] == name) {
      used_[i] = true;
      if (i + 1 >= args_.size()) {
        error_ = "option " + name + " needs a value";
        return fallback;
      }
      used_[i + 1] = true;
      value = args_[i + 1];
    } else if (args_[i].rfind(name + "=", 0) == 0) {
      used_[i] = true;
      value = args_[i].substr(name.size() + 1);
    }
  }
  return value;
}

std::vector<std::string> Args::positionals() {
  std::vector<std::string> out;
  bool ended = false;
  for (size_t i = 0; i < args_.size(); ++i) {
    if (used_[i]) continue;
    const std::string& a = args_[i];
    if (!ended && a == "--") {
      ended = true;
      continue;
    }
    if (!ended && a.size() > 1 && a[0] == '-') {
      if (error_.empty()) error_ = "unknown option '" + a + "'";
      continue;
    }
    out.push_back(a);
  }
  return out;
}

bool parse_threads(const std::string& text, int least, int* threads) {
  const char* b = text.data();
  const char* e = b + text.size();
  int n = 0;
  auto r = std::from_chars(b, e, n);
  if (r.ec != std::errc() || r.ptr != e || n < least || n > 1024) return false;
  *threads = n;
  return true;
}

bool parse_size(const std::string& text, uint64_t* bytes) {
  uint64_t n = 0;
  const char* b = text.data();
  const char* e = b + text.size();
  auto r = std::from_chars(b, e, n);
  if (r.ec != std::errc() || r.ptr == b || n == 0) return false;
  std::string unit(r.ptr, e);
  int shift = 0;
  if (!unit.empty()) {
    char u = static_cast<char>(std::toupper(static_cast<unsigned char>(unit[0])));
    shift = u == 'K' ? 10 : u == 'M' ? 20 : u == 'G' ? 30 : u == 'T' ? 40 : -1;
    std::string rest = unit.substr(1);
    if (shift < 0 || !(rest.empty() || rest == "B" || rest == "iB" || rest == "b")) return false;
  }
  if (shift > 0 && n > (~uint64_t{0} >> shift)) return false;
  *bytes = n << shift;
  return true;
}

bool parse_ratio(const std::string& text, double* ratio) {
  std::string t = text;
  double scale = 1;
  if (!t.empty() && t.back() == '%') {
    t.pop_back();
    scale = 0.01;
  }
  double r = 0;
  const auto res = std::from_chars(t.data(), t.data() + t.size(), r);
  if (t.empty() || res.ec != std::errc() || res.ptr != t.data() + t.size()) return false;
  r *= scale;
  if (!(r > 0 && r <= 1)) return false;
  *ratio = r;
  return true;
}

namespace {

extern "C" void on_signal(int sig) {
  remove_pending_outputs_from_signal();
  ::_exit(128 + sig);
}

// Whether standard output is a pipe or socket whose reader has gone: poll()
// reports POLLERR on such a write end.
bool stdout_reader_gone() {
  struct stat st;
  if (::fstat(STDOUT_FILENO, &st) != 0 || !(S_ISFIFO(st.st_mode) || S_ISSOCK(st.st_mode))) return false;
  struct pollfd p = {STDOUT_FILENO, POLLOUT, 0};
  return ::poll(&p, 1, 0) == 1 && (p.revents & (POLLERR | POLLHUP)) != 0;
}

// At exit: what stdio still holds for standard output must get there; a
// write that failed (now or earlier) must not end in status 0.
extern "C" void flush_stdout_at_exit() {
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  const int err = errno;
  if (flushed && !std::ferror(stdout)) return;
  if (err == EPIPE || stdout_reader_gone()) ::_exit(kExitBrokenPipe);
  std::fprintf(stderr, "psq: error: standard output: %s\n", err != 0 ? std::strerror(err) : "write failed");
  ::_exit(kExitFailure);
}

}  // namespace

void install_signal_cleanup() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
  ::sigaction(SIGHUP, &sa, nullptr);
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  ::sigaction(SIGPIPE, &ignore, nullptr);
  std::atexit(flush_stdout_at_exit);
}

}  // namespace psq::cli
