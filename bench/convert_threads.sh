#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# bench/convert_threads.sh: wall time of `psq convert` to .psq on one
# thread and on two (--threads 1 and 2): from a PLY (reader and converter,
# then the encoder) and from the .psq written (decoder, then the encoder,
# at 12 bits), in alternating runs so that the machine's drift hits both
# alike; checks that both write the same bytes.
#
#   bench/convert_threads.sh [--build DIR] [--runs N] [--tmpdir DIR] MESH.ply
#
# Prints one line per run (encode or reencode, threads, wall seconds, user
# seconds, peak RSS in KB), then the median wall time of each. Needs GNU time (/usr/bin/time).
set -euo pipefail
build=build runs=3 tmp=${TMPDIR:-/tmp}
while [ $# -gt 1 ]; do
  case $1 in
    --build) build=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --tmpdir) tmp=$2; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
[ $# -eq 1 ] || { echo "usage: $0 [--build DIR] [--runs N] [--tmpdir DIR] MESH.ply" >&2; exit 2; }
mesh=$1
psq=$build/psq
work=$(mktemp -d "$tmp/psq-threads.XXXXXX")
trap 'rm -rf "$work"' EXIT
log=$work/log

for _ in $(seq "$runs"); do
  for t in 1 2; do
    /usr/bin/time -f "encode $t %e %U %M" "$psq" convert -q -f --threads $t "$mesh" "$work/t$t.psq" 2>>"$log"
  done
done
cmp "$work/t1.psq" "$work/t2.psq"
for _ in $(seq "$runs"); do
  for t in 1 2; do
    /usr/bin/time -f "reencode $t %e %U %M" "$psq" convert -q -f --bits 12 --threads $t "$work/t1.psq" "$work/r$t.psq" 2>>"$log"
  done
done
cmp "$work/r1.psq" "$work/r2.psq"
echo "same bytes on one and two threads, from PLY and from .psq"
cat "$log"
for d in encode reencode; do
  for t in 1 2; do
    median=$(awk -v d=$d -v t=$t '$1 == d && $2 == t { print $3 }' "$log" | sort -n |
             awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }')
    echo "median $d threads $t: $median s"
  done
done
