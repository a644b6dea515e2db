#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# Regenerates the trained initial state of the .psq connectivity models
# (spec/psq-format.md 6.2.7 and Appendix C): codec/src/priors.cpp and the
# spec's table between <!-- priors:begin --> and <!-- priors:end -->.
#
# The training mesh is synthetic on purpose: psq-meshgen's default foam
# ball of 1M triangles (fixed seed), converted at 14 bits. None of the test
# meshes (../shared/data/meshes) enters the priors, so the size comparison
# on them stays out of sample. Changing the priors changes the bitstream:
# it needs a new format version, the conformance vectors and Appendix B.
#
# Usage: codec/tools/train_priors.sh [BUILD_DIR]   (default: build)
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-build}
case $build in /*) ;; *) build=$repo/$build ;; esac
for tool in psq psq-meshgen psq_train_priors; do
  [[ -x $build/$tool ]] || { echo "train_priors.sh: $build/$tool missing (build first)" >&2; exit 1; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$build/psq-meshgen" --triangles 1000000 -q -o "$tmp/foam.ply"
"$build/psq" convert -q "$tmp/foam.ply" "$tmp/foam.psq" --bits 14
"$build/psq_train_priors" "$tmp/foam.psq" --cpp "$tmp/priors.cpp" --md "$tmp/priors.md"
cp "$tmp/priors.cpp" "$repo/codec/src/priors.cpp"
python3 - "$repo/spec/psq-format.md" "$tmp/priors.md" <<'PY'
import sys
spec, table = sys.argv[1], open(sys.argv[2]).read()
s = open(spec).read()
b, e = "<!-- priors:begin -->\n", "<!-- priors:end -->"
i, j = s.index(b) + len(b), s.index(e)
open(spec, "w").write(s[:i] + table + s[j:])
PY
echo "train_priors.sh: wrote codec/src/priors.cpp and the table of spec Appendix C"
