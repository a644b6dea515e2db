#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Compares the .psq sizes that two psq binaries write for the same meshes:
# the quick check of a format or encoder experiment before a full
# bench/run_compare.sh. Each mesh is converted by both binaries at 11, 14
# and 16 bits and lossless (`psq convert -q --threads 1`); the table gives,
# per setting, NEW / OLD of the summed bytes and the median, smallest and
# largest per-mesh ratio, with the mesh where each extreme occurs.
#
# Usage: bench/size_ab.sh [-v] OLD_PSQ NEW_PSQ [MESH...]
#   default meshes: the .ply and .obj files of ../shared/data/meshes
#   -v   also print one row per mesh and setting
# Extra environment for the new binary only: NEW_ENV="NAME=value ..."
# (for experiments that read parameters from the environment).
set -euo pipefail
verbose=0
if [ "${1:-}" = "-v" ]; then verbose=1; shift; fi
[ $# -ge 2 ] || { sed -n '2,13p' "$0" >&2; exit 2; }
old=$1 new=$2; shift 2
for b in "$old" "$new"; do [ -x "$b" ] || { echo "size_ab.sh: $b is not an executable" >&2; exit 2; }; done
meshes=("$@")
if [ ${#meshes[@]} -eq 0 ]; then
  shared=$(cd "$(dirname "$0")/.." && pwd)/../shared/data/meshes
  for m in "$shared"/*.ply "$shared"/*.obj; do [ -f "$m" ] && meshes+=("$m"); done
fi
[ ${#meshes[@]} -gt 0 ] || { echo "size_ab.sh: no meshes" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rows=$tmp/rows
: > "$rows"
for m in "${meshes[@]}"; do
  name=$(basename "$m"); name=${name%.*}
  for q in 11 14 16 lossless; do
    if [ $q = lossless ]; then opt=(--lossless); else opt=(--bits "$q"); fi
    "$old" convert -q -f --threads 1 "${opt[@]}" "$m" "$tmp/old.psq" || { echo "size_ab.sh: $old failed on $m" >&2; exit 1; }
    env ${NEW_ENV:-} "$new" convert -q -f --threads 1 "${opt[@]}" "$m" "$tmp/new.psq" ||
      { echo "size_ab.sh: $new failed on $m" >&2; exit 1; }
    echo "$name $q $(stat -c %s "$tmp/old.psq") $(stat -c %s "$tmp/new.psq")" >> "$rows"
  done
done
python3 - "$rows" "$verbose" <<'PY'
import statistics, sys
rows = [line.split() for line in open(sys.argv[1])]
if sys.argv[2] == "1":
    print("| mesh | setting | old bytes | new bytes | new / old |")
    print("|---|---|---:|---:|---:|")
    for name, q, a, b in rows:
        print(f"| {name} | {q} | {int(a):,} | {int(b):,} | {int(b) / int(a):.4f} |")
    print()
print("| setting | meshes | old bytes | new bytes | new / old (sums) | median | smallest | largest |")
print("|---|---:|---:|---:|---:|---:|---|---|")
for q in ("11", "14", "16", "lossless"):
    sel = [(n, int(a), int(b)) for n, s, a, b in rows if s == q]
    ratios = sorted((b / a, n) for n, a, b in sel)
    ta, tb = sum(a for _, a, _ in sel), sum(b for _, _, b in sel)
    print(f"| {q} | {len(sel)} | {ta:,} | {tb:,} | {tb / ta:.4f} | {statistics.median(r for r, _ in ratios):.4f} | "
          f"{ratios[0][0]:.4f} {ratios[0][1]} | {ratios[-1][0]:.4f} {ratios[-1][1]} |")
PY
