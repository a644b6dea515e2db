// psq: the command-line tool. Thin glue over the libraries; see --help.
#include <cstdio>
#include <cstring>
#include <string>

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
    "  simplify IN OUT  simplify a mesh of any size out of core (--method clustering)\n"
    "\n"
    "Options:\n"
    "  -h, --help       show this help (psq COMMAND --help for a command's)\n"
    "  --version        print the version\n"
    "\n"
    "FILE may be '-' for standard input; OUT may be '-' for standard output.\n"
    "Exit status: 0 success, 1 data or I/O failure, 2 usage error.\n";

}  // namespace

int main(int argc, char** argv) {
  psq::cli::install_signal_cleanup();
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return psq::cli::kExitUsage;
  }
  std::string cmd = argv[1];
  if (cmd == "-h" || cmd == "--help" || cmd == "help") {
    std::fputs(kUsage, stdout);
    return psq::cli::kExitOk;
  }
  if (cmd == "--version" || cmd == "-V") {
    std::printf("psq %s\n", PSQ_VERSION);
    return psq::cli::kExitOk;
  }
  if (cmd == "info") return psq::cli::cmd_info(argc - 1, argv + 1);
  if (cmd == "convert") return psq::cli::cmd_convert(argc - 1, argv + 1);
  if (cmd == "dump") return psq::cli::cmd_dump(argc - 1, argv + 1);
  if (cmd == "verify") return psq::cli::cmd_verify(argc - 1, argv + 1);
  if (cmd == "simplify") return psq::cli::cmd_simplify(argc - 1, argv + 1);
  return psq::cli::usage_error("", "unknown command '" + cmd + "'");
}
