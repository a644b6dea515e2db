#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
# How far the texture slides when `psq simplify --method qem` simplifies a
# textured model (bench/RESULTS.md, "Simplifying textured models").
#
#   bench/simplify_textures.py --psq build/psq [--ratio 0.25] [--old-psq OTHER]
#
# The textured models of bench/attributes_vs_draco.py, as welded OBJs
# (texture coordinates and normals per corner). For each corner of the
# simplified OBJ, the point of the input surface that has the corner's
# texture coordinates (the input triangle holding them in texture space,
# the nearest such point where charts overlap) is compared with the
# corner's vertex: the distance, over the input's bounding-box diagonal, is
# how far the texture has slid there. Corners whose coordinates lie in no
# input triangle are not counted. Needs numpy and what
# attributes_vs_draco.py needs (assimp, assimp-testmodels).
import argparse
import os
import subprocess
import tempfile

import numpy as np

from attributes_vs_draco import textured_models, to_obj


def read_obj(path):
    """Positions, texture coordinates and the triangles' (v0 v1 v2 t0 t1 t2), from 0."""
    pos, tex, tri = [], [], []
    for line in open(path, errors='replace'):
        if line.startswith('v '):
            pos.append([float(x) for x in line.split()[1:4]])
        elif line.startswith('vt '):
            tex.append([float(x) for x in line.split()[1:3]])
        elif line.startswith('f '):
            c = [w.split('/') for w in line.split()[1:]]
            v = [int(x[0]) - 1 for x in c]
            t = [int(x[1]) - 1 for x in c]
            for k in range(1, len(c) - 1):
                tri.append((v[0], v[k], v[k + 1], t[0], t[k], t[k + 1]))
    return np.array(pos), np.array(tex), np.array(tri)


def slides(src, out):
    """Per corner of `out` found in `src`'s texture, the slide over src's diagonal."""
    pos, tex, tri = read_obj(src)
    pos2, tex2, tri2 = read_obj(out)
    diag = np.linalg.norm(pos.max(0) - pos.min(0))
    a, b, c = tex[tri[:, 3]], tex[tri[:, 4]], tex[tri[:, 5]]
    lo, hi = np.minimum(np.minimum(a, b), c) - 1e-5, np.maximum(np.maximum(a, b), c) + 1e-5
    m = np.stack([b - a, c - a], axis=2)  # per triangle: [[bu - au, cu - au], [bv - av, cv - av]]
    ok = np.abs(np.linalg.det(m)) > 1e-18
    inv = np.zeros_like(m)
    inv[ok] = np.linalg.inv(m[ok])
    found = []
    for t in range(len(tri2)):
        for k in range(3):
            uv, p = tex2[tri2[t, 3 + k]], pos2[tri2[t, k]]
            cand = np.where(ok & np.all(lo <= uv, axis=1) & np.all(hi >= uv, axis=1))[0]
            w = np.einsum('nij,nj->ni', inv[cand], uv - a[cand])
            inside = (w.min(axis=1) >= -1e-3) & (w.sum(axis=1) <= 1 + 1e-3)
            if not inside.any():
                continue
            i, w = cand[inside], w[inside]
            q = pos[tri[i, 0]] * (1 - w.sum(axis=1))[:, None] + pos[tri[i, 1]] * w[:, :1] + pos[tri[i, 2]] * w[:, 1:]
            found.append(np.linalg.norm(q - p, axis=1).min() / diag)
    return np.array(found)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--psq', default='build/psq')
    ap.add_argument('--old-psq', help='another psq, for a column of its slides')
    ap.add_argument('--ratio', default='0.25')
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix='psq_tex_')
    runs = [('psq', args.psq)] + ([('old', args.old_psq)] if args.old_psq else [])
    print('| mesh | triangles | ' + ' | '.join(f'{n}: triangles, median, 90th pct, over 1%' for n, _ in runs) + ' |')
    print('|---|---:|' + '---:|' * len(runs))
    for ply in sorted(textured_models(tmp)):
        name = os.path.basename(ply)[:-4]
        src = os.path.join(tmp, name + '.obj')
        to_obj(ply, src)
        cells = []
        for tag, psq in runs:
            out = os.path.join(tmp, f'{name}.{tag}.obj')
            subprocess.run([psq, 'simplify', '-q', '-f', src, out, '--method', 'qem', '--ratio', args.ratio], check=True)
            d = slides(src, out)
            count = sum(1 for line in open(out) if line.startswith('f '))
            cells.append(f'{count}, {np.median(d):.4f}, {np.percentile(d, 90):.4f}, {np.mean(d > 0.01):.1%}')
        faces = sum(1 for line in open(src) if line.startswith('f '))
        print(f'| {name} | {faces} | ' + ' | '.join(cells) + ' |')


if __name__ == '__main__':
    main()
