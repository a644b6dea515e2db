// SPDX-License-Identifier: Apache-2.0
// The plumbing that the sequence-filter commands (psq simplify --method qem, psq smooth)
// share: the input read as a processing sequence and pushed into a filter
// (a .psq through its decoder, any other mesh through the sequence
// builder), the filter's output written as .psq or as a mesh (PLY, OBJ,
// Draco), the output file committed only on success, progress and notes.
#ifndef PSQ_CLI_FILTER_IO_H_
#define PSQ_CLI_FILTER_IO_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cli_util.h"
#include "filter_output.h"
#include "progress.h"
#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/sequence.h"
#include "psq/sequence_builder.h"

namespace psq::cli {

// The options every filter command takes (see filter_options_help).
struct FilterOptions {
  std::string in, out;
  std::string to;
  std::string bits;  // empty: the input's (a quantized .psq), else 16
  bool lossless = false;
  std::string profile = "auto";
  uint64_t memory = uint64_t{64} << 20;
  std::string tmpdir;
  int threads = 2;
  bool force = false, quiet = false, json = false;
  // The output's expected size, for its segments (filter_segments()): a
  // triangle count, or a share of the input's; 0: not known.
  uint64_t output_triangles = 0;
  double output_share = 0;
};

// The help lines of those options.
extern const char kFilterOptionsHelp[];

// Reads the options above from `args` (before positionals()); "" or a
// usage message.
std::string parse_filter_options(Args& args, FilterOptions* o);

class FilterRun {
 public:
  FilterRun() = default;
  ~FilterRun();
  // Checks the options, opens IN and OUT and builds the output chain.
  // Returns -1 to go on, else the exit code (the error is reported).
  int open(const std::string& command, const FilterOptions& o);
  // Bytes the filter may use: --memory less the input side's share.
  uint64_t filter_budget() const { return filter_budget_; }
  bool input_is_psq() const { return static_cast<bool>(mesh_.decoder); }
  // The input's triangle count when it declares one, else -1.
  int64_t declared_triangles() const;
  // Counts the triangles of a .psq input by decoding it once more. Returns
  // -1 to go on, -2 when the input is standard input (nothing reported),
  // else the exit code (reported).
  int count_psq_triangles(uint64_t* count);
  // Where the filter writes.
  SequenceSink* sink() { return sink_.get(); }
  // Pushes the input into `filter`, begin to finish. `at_begin`, if set,
  // is called right before the filter's begin() with the triangles the
  // input yielded so far (all of them for a mesh input, which the sequence
  // builder reads completely first; none for a .psq).
  Status run(SequenceSink* filter, std::function<void(uint64_t)> at_begin = nullptr);
  // After run(): reports a failure, or commits OUT, prints the notes and the
  // summary line. Returns the exit code.
  int finish(const Status& run_status, const std::string& summary, const std::vector<std::string>& notes);
  uint64_t bytes_in() const;
  uint64_t bytes_out() const { return output_.size(); }
  double seconds() const { return progress_ ? progress_->seconds() : 0; }
  const std::string& input_format() const { return input_format_; }
  const std::string& output_format() const { return output_format_; }
  bool lossless() const { return encode_.lossless; }
  int bits() const { return encode_.lossless ? 0 : encode_.bits; }
  // Input notes (from the reader, and the sequence builder's).
  std::vector<std::string> input_notes() const;

 private:
  FilterOptions o_;
  OpenedMesh mesh_;
  OutputFile output_;
  EncodeOptions encode_;
  BuildOptions build_;
  BuildReport build_report_;
  MeshFormat out_format_ = MeshFormat::kUnknown;
  std::string input_format_, output_format_;
  uint64_t filter_budget_ = 0;
  std::unique_ptr<Progress> progress_;
  detail::FilterOutput chain_;
  std::unique_ptr<SequenceSink> sink_;
};

}  // namespace psq::cli

#endif  // PSQ_CLI_FILTER_IO_H_
