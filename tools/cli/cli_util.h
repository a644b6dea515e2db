// SPDX-License-Identifier: Apache-2.0
// Shared pieces of the psq command-line tool: argument parsing, diagnostics
// and exit codes (STYLE.md: data on stdout only, diagnostics on stderr as
// "psq: error: FILE: message"; exit 0 success, 1 data or I/O failure, 2 usage).
#ifndef PSQ_CLI_UTIL_H_
#define PSQ_CLI_UTIL_H_

#include <cstdint>
#include <string>
#include <vector>

#include "json.h"
#include "pipeline.h"
#include "psq/status.h"

namespace psq::cli {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;
// The reader of standard output (or of an output pipe) went away, as when
// "psq ... | head" has what it wants: the status a shell shows for a
// process killed by SIGPIPE (128 + 13), which is how GNU tools end there.
constexpr int kExitBrokenPipe = 141;

// Prints "psq: error: FILE: <status>" and returns the exit code for it:
// 2 for kUsage, 1 otherwise; but for a write that failed because the
// output pipe's reader had gone (output_pipe_closed()), prints nothing and
// returns kExitBrokenPipe.
int report_error(const std::string& file, const Status& status);
// For an error of a pipeline from IN to OUT: a status that names a place
// (line or byte) or is about the data (any code but kIo) is about IN; an
// I/O error without a place (a write failure) is about OUT.
int report_pipeline_error(const std::string& in, const std::string& out, const Status& status);
// Prints "psq: error: MESSAGE" and a hint to the command's --help; returns 2.
int usage_error(const std::string& command, const std::string& message);
// Prints "psq: warning: FILE: MESSAGE".
void warn(const std::string& file, const std::string& message);
// Prints "psq: note: FILE: MESSAGE".
void note(const std::string& file, const std::string& message);

// A minimal option parser: flags (--json), options with a value (--to ply or
// --to=ply) and positional arguments; "--" ends options; "-" is positional.
class Args {
 public:
  Args(int argc, char** argv, int first);
  // True and consumed if the flag is present.
  bool flag(const std::string& name, const std::string& alias = "");
  // The value of an option, or `fallback`. Sets error() when the option has
  // no value.
  std::string option(const std::string& name, const std::string& fallback = "");
  // After all flag()/option() calls: the rest; any unconsumed "-x"/"--x" is an
  // error (unknown option).
  std::vector<std::string> positionals();
  const std::string& error() const { return error_; }

 private:
  std::vector<std::string> args_;
  std::vector<bool> used_;
  std::string error_;
  bool options_ended_at(size_t i) const;
};

// JSON text (tools/src/ops/json.h).
using detail::json_escape;
using detail::json_number;

// Parses a byte size: a number with an optional K, M, G or T suffix (powers
// of 1024; "MiB", "MB" and "M" all mean 2^20). False when malformed or zero.
bool parse_size(const std::string& text, uint64_t* bytes);
// Parses a fraction of the input to keep: "0.1" or "10%", in (0, 1]. False
// when malformed or out of range.
bool parse_ratio(const std::string& text, double* ratio);
// A --threads value: a whole number from `least` to 1024.
bool parse_threads(const std::string& text, int least, int* threads);

// Whether two paths name the same existing file (tools/src/ops/pipeline.h).
using detail::same_file;

// Installs SIGINT/SIGTERM/SIGHUP handlers that remove pending temporary
// outputs and exit with 128 + the signal (130, 143, 129).
//
// SIGPIPE is ignored instead: a write to a pipe whose reader has gone
// ("psq convert big.ply - --to ply | head -c 100") fails with EPIPE, the
// command unwinds as for any error (its temporary files are removed), and
// psq exits quietly with kExitBrokenPipe (141), the status GNU tools end
// with there; no message, since the reader wanted no more. Data already
// written to a pipe cannot be taken back; any other failure still exits 1
// with its one line. The same holds for what stdio buffered for standard
// output (summaries, --json, help): at exit it is flushed, and a failure
// exits 141 quietly when the pipe's reader has gone, else 1 with one line
// ("psq: error: standard output: ...").
void install_signal_cleanup();

}  // namespace psq::cli

#endif  // PSQ_CLI_UTIL_H_
