#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Speed ratios of psq codecs against a reference codec, each ratio taken
# within one invocation of psq_bench_compare, so that the machine's drift
# between invocations (10% and more between hours on the project's shared
# 2-core VM) cancels. Each round runs psq_bench_compare once per mesh with
# --best --runs N on the listed codecs and the reference; the table gives
# every round's ratio (codec / reference, M triangles/s) and their median,
# for encoding and decoding.
#
# Usage: bench/speed_ratio.sh [--build DIR] [--rounds R] [--runs N]
#                             [--codecs A,B] [--ref CODEC] [--pin CPU] MESH...
#   defaults: --build build, --rounds 5, --runs 11,
#             --codecs psq-fast-q16-seq,psq-fast-q16-arrays, --ref draco-q16-cl7
#   --pin CPU runs every invocation on that processor (taskset), so that
#   psq's and the reference's children share one; on a shared virtual
#   machine whose processors are not equally loaded, an unpinned child
#   lands on either and a round's ratio moves by 30% and more.
# A -seq codec is reported for encoding only (its encoder alone, from a
# recorded processing sequence), an -arrays codec for decoding only (into
# vertex and index arrays); other codecs for both.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=$repo/build
rounds=5
runs=11
codecs=psq-fast-q16-seq,psq-fast-q16-arrays
ref=draco-q16-cl7
pin=
meshes=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --codecs) codecs=$2; shift 2 ;;
    --ref) ref=$2; shift 2 ;;
    --pin) pin=$2; shift 2 ;;
    -h|--help) sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "speed_ratio.sh: unknown option $1" >&2; exit 2 ;;
    *) meshes+=("$1"); shift ;;
  esac
done
bin=$build/bench/psq_bench_compare
[ -x "$bin" ] || { echo "speed_ratio.sh: $bin not found; build with -DPSQ_BUILD_BENCH=ON" >&2; exit 2; }
[ ${#meshes[@]} -gt 0 ] || { echo "speed_ratio.sh: no mesh given (see --help)" >&2; exit 2; }
command -v python3 >/dev/null || { echo "speed_ratio.sh: needs python3" >&2; exit 2; }
run=()
if [ -n "$pin" ]; then
  command -v taskset >/dev/null || { echo "speed_ratio.sh: --pin needs taskset (util-linux)" >&2; exit 2; }
  run=(taskset -c "$pin")
fi
tmp=$(mktemp -d "${TMPDIR:-/tmp}/psq-ratio-XXXXXX")
trap 'rm -rf "$tmp"' EXIT
for ((r = 1; r <= rounds; ++r)); do
  for m in "${meshes[@]}"; do
    "${run[@]}" "$bin" --best --runs "$runs" -q --codecs "$codecs,$ref" --json "$tmp/r$(printf %04d "$r")_$(basename "$m").json" "$m" \
      > /dev/null || { echo "speed_ratio.sh: psq_bench_compare failed on $m" >&2; exit 1; }
  done
done
python3 - "$tmp" "$codecs" "$ref" "$rounds" "$runs" <<'PY'
import glob, json, os, statistics, sys
tmp, codecs, ref, rounds, runs = sys.argv[1], sys.argv[2].split(","), sys.argv[3], int(sys.argv[4]), sys.argv[5]

def rate(triangles, entry, direction):
    """M triangles/s of one codec entry's fastest run in a direction, or None."""
    if not entry or not entry.get("ok"):
        return None
    seconds = [t for t in entry.get(direction + "_seconds", []) if t > 0]
    return triangles / min(seconds) / 1e6 if seconds else None

# {mesh: {codec: [(encode, decode) per round]}}
table = {}
for path in sorted(glob.glob(os.path.join(tmp, "r*.json"))):
    with open(path) as f:
        doc = json.load(f)
    for mesh in doc["meshes"]:
        per = table.setdefault(os.path.basename(mesh["mesh"]), {})
        by = {c["codec"]: c for c in mesh["codecs"]}
        n = mesh["triangles"]
        for c in codecs + [ref]:
            per.setdefault(c, []).append((rate(n, by.get(c), "encode"), rate(n, by.get(c), "decode")))

print("Ratios of M triangles/s to %s within each invocation (`--best --runs %s`), %d rounds:" % (ref, runs, rounds))
print()
print("| mesh | codec | direction | ratios by round | median |")
print("|---|---|---|---|---:|")
for mesh, per in table.items():
    for c in codecs:
        for d, name in ((0, "encode"), (1, "decode")):
            # -seq codecs time the encoder alone, -arrays the decoder into arrays.
            if (c.endswith("-seq") and name == "decode") or (c.endswith("-arrays") and name == "encode"):
                continue
            ratios = [a[d] / b[d] for a, b in zip(per[c], per[ref]) if a[d] and b[d]]
            if not ratios:
                continue
            print("| %s | %s | %s | %s | **%.2f** |" % (mesh, c, name, ", ".join("%.2f" % x for x in ratios),
                                                        statistics.median(ratios)))
PY
