// SPDX-License-Identifier: Apache-2.0
// The psq subcommands; each takes its own argv slice and returns an exit code.
#ifndef PSQ_CLI_COMMANDS_H_
#define PSQ_CLI_COMMANDS_H_

namespace psq::cli {

int cmd_info(int argc, char** argv);     // argv[0] is "info"
int cmd_convert(int argc, char** argv);  // argv[0] is "convert"
int cmd_dump(int argc, char** argv);     // argv[0] is "dump"
int cmd_verify(int argc, char** argv);   // argv[0] is "verify"
int cmd_distance(int argc, char** argv); // argv[0] is "distance"
int cmd_simplify(int argc, char** argv); // argv[0] is "simplify"
int cmd_smooth(int argc, char** argv);   // argv[0] is "smooth"
int cmd_simplify_qem(int argc, char** argv);  // argv[0] is "simplify", with --method qem

}  // namespace psq::cli

#endif  // PSQ_CLI_COMMANDS_H_
