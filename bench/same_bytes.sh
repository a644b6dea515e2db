#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Checks that two psq binaries write the same bytes: the check of a
# refactoring or speed change that must leave the format alone. Both
# binaries convert the shared meshes with both back-ends at 11 and 16 bits
# and lossless, and the attribute inputs (normals, colours, scalar columns,
# corner normals and texture coordinates) with normals at 8 bits and
# texture coordinates at 10, in one segment and in segments of 40,000
# triangles; the new binary then decodes each attribute, segmented and
# 16-bit rANS file to PLY and verifies it, and the old one decodes the
# same files. Prints the files that differ; exits 1 if any does.
#
# Usage: bench/same_bytes.sh OLD_PSQ NEW_PSQ
#   inputs: ../shared/data/meshes/*.ply, four files of ../shared/data/inputs
#   or tests, assimp's spider.obj and WusonOBJ.obj when installed
#   (Debian package assimp-testmodels), and a 300k-triangle psq-meshgen
#   foam when psq-meshgen sits beside NEW_PSQ.
set -euo pipefail
shopt -s nullglob
[ $# -eq 2 ] || { sed -n '2,17p' "$0" >&2; exit 2; }
old=$(realpath "$1") new=$(realpath "$2")
repo=$(cd "$(dirname "$0")/.." && pwd)
shared=$repo/../shared/data
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
attr=("$shared"/inputs/fandisk.rich.ply "$shared"/inputs/bun_zipper_ascii.ply
      /usr/share/assimp/models/OBJ/spider.obj /usr/share/assimp/models/OBJ/WusonOBJ.obj)
if [ -x "$(dirname "$new")/psq-meshgen" ]; then
  "$(dirname "$new")/psq-meshgen" --triangles 300k -o "$tmp/foam300k.ply" > /dev/null
  attr+=("$tmp/foam300k.ply")
fi
run() {  # $1 binary, $2 output directory
  local psq=$1 out=$2 m n p o t f
  mkdir -p "$out"
  for m in "$shared"/meshes/*.ply; do
    n=$(basename "${m%.*}")
    for p in compact fast; do
      for o in "--bits 11" "--bits 16" "--lossless"; do
        t=$(echo "$o" | tr -d ' -')
        # shellcheck disable=SC2086
        "$psq" convert -q -f --threads 1 --profile $p $o "$m" "$out/$n.$p.$t.psq"
      done
    done
  done
  for m in "${attr[@]}"; do
    [ -f "$m" ] || continue
    n=$(basename "${m%.*}")
    for p in compact fast; do
      "$psq" convert -q -f --threads 1 --profile $p --normal-bits 8 --uv-bits 10 "$m" "$out/$n.$p.attr.psq"
      "$psq" convert -q -f --threads 1 --profile $p --normal-bits 8 --uv-bits 10 --segment 40000 "$m" "$out/$n.$p.seg.psq"
    done
  done
  for f in "$out"/*.attr.psq "$out"/*.seg.psq "$out"/*.fast.bits16.psq; do
    "$psq" convert -q -f "$f" "${f%.psq}.dec.ply"
    "$psq" verify -q "$f"
  done
}
run "$old" "$tmp/old"
run "$new" "$tmp/new"
differ=0
for f in "$tmp"/old/*; do
  n=$(basename "$f")
  cmp -s "$f" "$tmp/new/$n" || { echo "differs: $n"; differ=1; }
done
echo "$(ls "$tmp/old" | wc -l) files compared"
exit $differ
