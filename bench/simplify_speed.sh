#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Whole-process speed and peak memory of psq simplify --method clustering,
# .psq to .psq, on generated foam meshes (psq-meshgen) at about 1% and 10%
# of the input triangles: wall and CPU time, peak RSS (/usr/bin/time), input
# triangles per second, and the filter's own peak from --json. The grid for
# each ratio comes from a --triangles run (its trial passes are not timed).
# --memory is the default 256M, and 8G for --cells global.
# The meshes are generated in $TMPDIR and deleted afterwards.
#
#   bench/simplify_speed.sh [BUILD_DIR] [SIZES] [CELL_MODES] [THREADS]
#   bench/simplify_speed.sh build "10M 50M" "connected" "1 3"
set -euo pipefail
build=${1:-build}
sizes=${2:-10M 50M}
modes=${3:-connected}
threads=${4:-1 3}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/psq-simplify-XXXXXX")
trap 'rm -rf "$tmp"' EXIT

echo "| input T | cells | target | grid | T out | threads | wall (s) | CPU (s) | peak RSS (MiB) | filter peak (MiB) | M input T/s |"
echo "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in $sizes; do
  "$build/psq-meshgen" --triangles "$n" -q -f -o "$tmp/big.ply"
  "$build/psq" convert -q -f "$tmp/big.ply" "$tmp/big.psq"
  rm -f "$tmp/big.ply"
  tris=$("$build/psq" info --json "$tmp/big.psq" | grep -o '"triangles": [0-9]*' | head -1 | grep -o '[0-9]*$')
  for pct in 1 10; do
    target=$((tris * pct / 100))
    grid=$("$build/psq" simplify -q -f --json --triangles "$target" "$tmp/big.psq" "$tmp/out.psq" |
           grep -o '"grid_longest": [0-9.e+]*' | grep -o '[0-9.e+]*$')
    for cells in $modes; do
      # The global mode keeps every occupied cell: give it room.
      mem=256M
      [ "$cells" = global ] && mem=8G
      for t in $threads; do
        /usr/bin/time -f "%e %U %S %M" -o "$tmp/time" "$build/psq" simplify -q -f --json --threads "$t" \
          --memory "$mem" --cells "$cells" --grid "$grid" "$tmp/big.psq" "$tmp/out.psq" > "$tmp/out.json"
        read -r wall user sys kb < "$tmp/time"
        out=$(grep -o '"triangles": [0-9]*' "$tmp/out.json" | grep -o '[0-9]*$')
        peak=$(grep -o '"filter_peak_bytes": [0-9]*' "$tmp/out.json" | grep -o '[0-9]*$')
        awk -v n="$tris" -v c="$cells" -v p="$pct" -v g="$grid" -v o="$out" -v t="$t" -v w="$wall" -v u="$user" \
            -v s="$sys" -v k="$kb" -v f="$peak" \
          'BEGIN { printf "| %d | %s | %s%% | %.1f | %d | %d | %.2f | %.2f | %.1f | %.1f | %.2f |\n",
                   n, c, p, g, o, t, w, u + s, k / 1024, f / 1048576, n / w / 1e6 }'
      done
    done
  done
done
