#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The paper's Table 2 (Isenburg et al. 2003, section 5.1) for psq simplify
# --method clustering: for each mesh and grid, the original OoCS (--cells
# global) against active cells and connected layers: output triangles and
# vertices, non-manifold output vertices and edges, the non-manifold
# vertices removed per vertex added (relative to global), the filter's peak
# memory, time and input triangles per second. Prints a Markdown table.
#
#   bench/simplify_table2.sh [BUILD_DIR] [MESH.ply:GRID,GRID,GRID ...]
#   bench/simplify_table2.sh build ../shared/data/meshes/blade.ply:32,64,128
#
# Default meshes: the shared blade and turbine (thin parts, handles) and
# the generated isosurfaces (many components and handles) at three grids.
set -euo pipefail
build=${1:-build}
shift || true
data=$(cd "$(dirname "$0")/../.." && pwd)/shared/data/meshes
if [ $# -eq 0 ]; then
  set -- "$data/blade.ply:24,48,96" "$data/turbine.ply:24,48,96" \
         "$data/iso_ball_200k.ply:32,64,96" "$data/iso_labyrinth_200k.ply:32,64,96"
fi
tmp=$(mktemp -d "${TMPDIR:-/tmp}/psq-table2-XXXXXX")
trap 'rm -rf "$tmp"' EXIT

echo "| mesh | T in | grid | T out | cells | V out | V nm | E nm | dV nm / dV out | filter peak (KiB) | time (s) | T in/s |"
echo "|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"
for spec in "$@"; do
  mesh=${spec%%:*}
  grids=${spec##*:}
  # From .psq, as the paper reads its input from a compressed sequence.
  "$build/psq" convert -q -f "$mesh" "$tmp/in.psq"
  for g in ${grids//,/ }; do
    for cells in global active connected; do
      # --memory: room for the global mode, whose cells all stay in memory.
      "$build/psq" simplify -q -f --threads 1 --memory 4G --grid "$g" --cells "$cells" --json "$tmp/in.psq" \
        "$tmp/out.psq" > "$tmp/$cells.json"
    done
    /usr/bin/python3 - "$tmp" "$(basename "$mesh" .ply)" "$g" <<'PY'
import json, sys
tmp, name, grid = sys.argv[1:4]
rows = {c: json.load(open(f"{tmp}/{c}.json")) for c in ("global", "active", "connected")}
g = rows["global"]
for c, d in rows.items():
    dv = d["vertices"] - g["vertices"]
    ratio = "-" if c == "global" or dv == 0 else f"{100.0 * (g['nonmanifold_vertices'] - d['nonmanifold_vertices']) / dv:.0f}%"
    first = c == "global"
    print(f"| {name if first else ''} | {d['triangles_in'] if first else ''} | {grid if first else ''} | "
          f"{d['triangles'] if first else ''} | {c} | {d['vertices']} | {d['nonmanifold_vertices']} | "
          f"{d['nonmanifold_edges']} | {ratio} | {d['filter_peak_bytes'] / 1024:.0f} | {d['seconds']:.3f} | "
          f"{d['triangles_per_second'] / 1e6:.2f}M |")
PY
  done
done
