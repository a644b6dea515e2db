#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Instructions per triangle of psq's and Draco's encoders and decoders,
# counted by callgrind: a measure of the codecs' work that does not depend
# on the machine's load (the timings of bench/run_compare.sh vary by up to
# 2x between runs on a shared virtual machine; these counts do not vary).
#
# For each mesh it runs `psq_bench_compare --once encode|decode` under
# valgrind, collecting only inside the one operation (once_operation in
# compare.cpp): the psq encoder alone on a recorded processing sequence
# (psq-q16-seq, the codec issue's encode criterion), the psq decoder on its
# bytes, and Draco's edgebreaker at -cl 7 (draco-q16-cl7), all at 16 bits.
# Instructions are not time: branch mispredictions and cache misses differ
# between the codecs (on this machine psq decoded about 4.2 G instructions
# per second, Draco about 3.2 G, in the runs of 2026-11-22).
#
# Usage: bench/instructions.sh [--build DIR] [MESH...]
#   default meshes: the shared meshes of 200k triangles and more
# Needs valgrind (Debian package valgrind).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=$repo/build
meshes=()
while [ $# -gt 0 ]; do
  case $1 in
    --build) build=$2; shift 2 ;;
    -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
    *) meshes+=("$1"); shift ;;
  esac
done
tool=$build/bench/psq_bench_compare
[ -x "$tool" ] || { echo "instructions.sh: $tool missing (build with the benchmarks)" >&2; exit 1; }
command -v valgrind >/dev/null || { echo "instructions.sh: valgrind missing (apt-get install valgrind)" >&2; exit 1; }
if [ ${#meshes[@]} -eq 0 ]; then
  shared=$repo/../shared/data/meshes
  meshes=("$shared/iso_ball_200k.ply" "$shared/iso_ball_200k_shuffled.ply" "$shared/iso_labyrinth_200k.ply")
fi

count() {  # PHASE CODEC MESH -> "instructions triangles"
  local out
  out=$(valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*once_operation*' \
          --callgrind-out-file=/dev/null "$tool" --once "$1" --codecs "$2" "$3" 2>&1)
  local ir tri
  ir=$(echo "$out" | sed -n 's/.*I *refs: *//p' | tr -d ,)
  tri=$(echo "$out" | sed -n 's/^once .* triangles \([0-9]*\) .*/\1/p')
  [ -n "$ir" ] && [ -n "$tri" ] || { echo "instructions.sh: $2 $1 failed on $3:" >&2; echo "$out" | tail -5 >&2; exit 1; }
  echo "$ir $tri"
}

echo "| mesh | triangles | decode psq | decode Draco | psq / Draco | encode psq (from a sequence) | encode Draco | psq / Draco |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for m in "${meshes[@]}"; do
  read -r pd tri < <(count decode psq-q16-seq "$m")
  read -r dd _ < <(count decode draco-q16-cl7 "$m")
  read -r pe _ < <(count encode psq-q16-seq "$m")
  read -r de _ < <(count encode draco-q16-cl7 "$m")
  awk -v n="$(basename "$m" .ply)" -v t="$tri" -v pd="$pd" -v dd="$dd" -v pe="$pe" -v de="$de" 'BEGIN {
    printf "| %s | %d | %.0f | %.0f | %.2f | %.0f | %.0f | %.2f |\n", n, t, pd / t, dd / t, pd / dd, pe / t, de / t, pe / de }'
done
echo
echo "Instructions per triangle (callgrind), 16 bits; Draco at -cl 7. Command: bench/instructions.sh --build ${build#$repo/}"
