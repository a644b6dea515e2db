// SPDX-License-Identifier: Apache-2.0
// psq: the command-line tool. Thin glue over the libraries; see --help.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "cli_util.h"
#include "commands.h"

namespace {

const char kUsage[] =
    "Usage: psq COMMAND [OPTIONS] ...\n"
    "\n"
    "psq reads and writes triangle meshes as streams: PLY, OBJ (and OFF, STL\n"
    "input) and compressed processing sequences (.psq).\n"
    "\n"
    "Commands:\n"
    "  info FILE        counts, properties, bounding box and defects of a mesh\n"
    "  convert IN OUT   convert between PLY, OBJ and .psq, streaming\n"
    "  dump IN          print the processing sequence of a mesh as text\n"
    "  verify FILE      decode a .psq completely and check it\n"
    "  distance A B     surface distance between two meshes (Metro: max, mean, RMS)\n"
    "  simplify IN OUT  simplify a mesh of any size out of core (--method\n"
    "                   clustering or qem)\n"
    "  smooth IN OUT    smooth a mesh of any size (Taubin), streaming\n"
    "\n"
    "Options:\n"
    "  -h, --help       show this help (psq help COMMAND or psq COMMAND --help\n"
    "                   for a command's)\n"
    "  --version        print the version\n"
    "\n"
    "FILE may be '-' for standard input; OUT may be '-' for standard output.\n"
    "Exit status: 0 success, 1 data or I/O failure, 2 usage error, 141 (quietly)\n"
    "when the reader of standard output goes away (psq ... | head).\n";

struct Command {
  const char* name;
  int (*run)(int argc, char** argv);
};

const Command kCommands[] = {
    {"info", psq::cli::cmd_info},
    {"convert", psq::cli::cmd_convert},
    {"dump", psq::cli::cmd_dump},
    {"verify", psq::cli::cmd_verify},
    {"simplify", psq::cli::cmd_simplify},
    {"distance", psq::cli::cmd_distance},
    {"smooth", psq::cli::cmd_smooth},
};

const Command* find_command(const std::string& name) {
  for (const Command& c : kCommands) {
    if (name == c.name) return &c;
  }
  return nullptr;
}

// Levenshtein distance, for suggesting the command a typo meant.
size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// "unknown command 'X'", with the nearest command when one is near (at most
// two edits, or a prefix of it).
int unknown_command(const std::string& name) {
  const Command* best = nullptr;
  size_t best_distance = 3;
  for (const Command& c : kCommands) {
    size_t d = std::string(c.name).rfind(name, 0) == 0 && !name.empty() ? 1 : edit_distance(name, c.name);
    if (d < best_distance) {
      best_distance = d;
      best = &c;
    }
  }
  std::string message = "unknown command '" + name + "'";
  if (best) message += " (did you mean '" + std::string(best->name) + "'?)";
  return psq::cli::usage_error("", message);
}

}  // namespace

int main(int argc, char** argv) {
  psq::cli::install_signal_cleanup();
#ifdef __GLIBC__
  // Arrays of 128 KiB and more get pages of their own, returned when freed.
  // glibc's default raises this threshold to the largest block freed so
  // far, so that once a growing array (a simplifier's clusters, the
  // converter's records) has doubled, later large blocks come from the
  // heap, whose freed middle stays resident and counts against --memory
  // (bench/RESULTS.md, "Speed and memory at 50M and 200M triangles").
  mallopt(M_MMAP_THRESHOLD, 128 << 10);
#endif
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return psq::cli::kExitUsage;
  }
  std::string cmd = argv[1];
  if (cmd == "help" && argc > 2) {
    // psq help COMMAND: the command's own --help.
    const Command* c = find_command(argv[2]);
    if (!c) return unknown_command(argv[2]);
    char help_flag[] = "--help";
    char* help_argv[] = {argv[2], help_flag, nullptr};
    return c->run(2, help_argv);
  }
  if (cmd == "-h" || cmd == "--help" || cmd == "help") {
    std::fputs(kUsage, stdout);
    return psq::cli::kExitOk;
  }
  if (cmd == "--version" || cmd == "-V") {
    std::printf("psq %s\n", PSQ_VERSION);
    return psq::cli::kExitOk;
  }
  if (const Command* c = find_command(cmd)) return c->run(argc - 1, argv + 1);
  return unknown_command(cmd);
}
