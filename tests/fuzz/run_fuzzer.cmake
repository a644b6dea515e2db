# SPDX-License-Identifier: Apache-2.0
# Runs one libFuzzer target for a bounded time, for ctest (label "fuzz").
#
#   cmake -DFUZZER=<binary> -DCORPUS=<seed dir> -DWORK_DIR=<scratch dir>
#         [-DDICT=<file>] [-DSECONDS=20] [-DEXTRA_ARGS=<flag;flag...>]
#         -P run_fuzzer.cmake
#
# libFuzzer adds the inputs it finds to the FIRST corpus directory given, so
# a fresh, empty WORK_DIR/new comes first and the seed corpus from the source
# tree second: the source tree is only read. Crash, leak and timeout
# reproducers are written to WORK_DIR/artifacts/ (the failing test prints
# their path); rerun one with `<fuzzer> <file>`.
foreach(var FUZZER CORPUS WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run_fuzzer.cmake: -D${var}=... is required")
  endif()
endforeach()
if(NOT DEFINED SECONDS)
  set(SECONDS 20)
endif()

file(REMOVE_RECURSE "${WORK_DIR}/new")
file(MAKE_DIRECTORY "${WORK_DIR}/new" "${WORK_DIR}/artifacts")

set(args
  -max_total_time=${SECONDS}
  -rss_limit_mb=2048
  -timeout=10
  -print_final_stats=1
  "-artifact_prefix=${WORK_DIR}/artifacts/")
# EXTRA_ARGS come last: libFuzzer takes the last value of a flag, so a
# target may change the ones above (fuzz_drc its -timeout).
if(DEFINED DICT AND NOT DICT STREQUAL "")
  list(APPEND args "-dict=${DICT}")
endif()
if(DEFINED EXTRA_ARGS)
  list(APPEND args ${EXTRA_ARGS})
endif()

# Report UBSan findings as crashes (in case the code was built with
# recoverable checks) and with their stack.
set(ENV{UBSAN_OPTIONS} "halt_on_error=1:print_stacktrace=1")
if(NOT DEFINED ENV{ASAN_OPTIONS})
  set(ENV{ASAN_OPTIONS} "detect_leaks=1")
endif()

execute_process(
  COMMAND "${FUZZER}" ${args} "${WORK_DIR}/new" "${CORPUS}"
  WORKING_DIRECTORY "${WORK_DIR}"
  RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  file(GLOB found "${WORK_DIR}/artifacts/*")
  message(FATAL_ERROR "${FUZZER} failed (${rc}); reproducer(s): ${found}")
endif()
