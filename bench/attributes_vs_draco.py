#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
# Sizes of meshes with normals, texture coordinates and colours in .psq
# (both profiles) beside Draco's at the same quantization, and psq's
# attribute errors (spec/psq-format.md 8.3; bench/RESULTS.md, "Attributes
# beside Draco").
#
#   bench/attributes_vs_draco.py --psq build/psq [--normal-bits 8 --uv-bits 10]
#
# Inputs, written to a temporary directory:
# - real artist models with normals and texture coordinates from Debian's
#   assimp-testmodels (BSD-3-Clause), made PLY by assimp-utils' `assimp
#   export -jiv -tri -ptv` (one vertex per distinct position, normal and
#   texture coordinate: seams become split vertices), and the spider OBJ
#   split the same way;
# - shared meshes (../shared/data) with area-weighted vertex normals, as a
#   scanner's software writes them;
# - fandisk.rich.ply (normals and uchar colours, synthetic), welded and
#   made float.
# Draco reads each mesh as OBJ when it has texture coordinates (its PLY
# reader drops them) and as PLY otherwise; it runs as
# `draco_encoder -qp 14 -qn 8 -qt 10 -cl 7`, psq as
# `psq convert --bits 14 --normal-bits N --uv-bits M --profile P`.
# Needs: draco_encoder (Debian package draco), assimp (assimp-utils),
# /usr/share/assimp/models (assimp-testmodels).
import argparse
import math
import os
import statistics
import struct
import subprocess
import sys
import tempfile

ASSIMP = '/usr/share/assimp/models'
SHARED = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'shared', 'data')
T = {'char': 'b', 'int8': 'b', 'uchar': 'B', 'uint8': 'B', 'short': 'h', 'int16': 'h', 'ushort': 'H',
     'uint16': 'H', 'int': 'i', 'int32': 'i', 'uint': 'I', 'uint32': 'I', 'float': 'f', 'float32': 'f',
     'double': 'd', 'float64': 'd'}
R = {'b': 'char', 'B': 'uchar', 'h': 'short', 'H': 'ushort', 'i': 'int', 'I': 'uint', 'f': 'float', 'd': 'double'}


def read_ply(path):
    data = open(path, 'rb').read()
    nl = data.index(b'\n', data.index(b'end_header')) + 1
    fmt, elems = None, []
    for line in data[:nl].decode('latin1').splitlines():
        w = line.split()
        if not w:
            continue
        if w[0] == 'format':
            fmt = w[1]
        elif w[0] == 'element':
            elems.append([w[1], int(w[2]), []])
        elif w[0] == 'property':
            elems[-1][2].append((w[4], T[w[2]], T[w[3]]) if w[1] == 'list' else (w[2], T[w[1]], None))
    out, pos = {}, nl
    if fmt == 'ascii':
        toks, ti = data[nl:].split(), 0
        for name, n, props in elems:
            rows = []
            for _ in range(n):
                row = []
                for _, t, lt in props:
                    if lt is None:
                        row.append(float(toks[ti]) if t in 'fd' else int(toks[ti]))
                        ti += 1
                    else:
                        c = int(toks[ti])
                        row.append([float(x) if lt in 'fd' else int(x) for x in toks[ti + 1:ti + 1 + c]])
                        ti += 1 + c
                rows.append(row)
            out[name] = (props, rows)
        return out
    e = '<' if fmt == 'binary_little_endian' else '>'
    for name, n, props in elems:
        rows = []
        for _ in range(n):
            row = []
            for _, t, lt in props:
                if lt is None:
                    row.append(struct.unpack_from(e + t, data, pos)[0])
                    pos += struct.calcsize(t)
                else:
                    c = struct.unpack_from(e + t, data, pos)[0]
                    pos += struct.calcsize(t)
                    row.append(list(struct.unpack_from(e + lt * c, data, pos)))
                    pos += struct.calcsize(lt) * c
            rows.append(row)
        out[name] = (props, rows)
    return out


def write_ply(path, vprops, verts, faces):
    head = ['ply', 'format binary_little_endian 1.0', 'element vertex %d' % len(verts)]
    head += ['property %s %s' % (R[t], n) for n, t, _ in vprops]
    head += ['element face %d' % len(faces), 'property list uchar int vertex_indices', 'end_header']
    s = struct.Struct('<' + ''.join(t for _, t, _ in vprops))
    b = bytearray(('\n'.join(head) + '\n').encode())
    for v in verts:
        b += s.pack(*v)
    for f in faces:
        b += struct.pack('<B3i', 3, *f)
    open(path, 'wb').write(b)


def faces_of(m):
    props, rows = m['face']
    k = [i for i, p in enumerate(props) if p[2] is not None][0]
    out = []
    for r in rows:
        c = r[k]
        out += [(c[0], c[i], c[i + 1]) for i in range(1, len(c) - 1)]
    return out


def split_obj(src, dst):
    """An OBJ as PLY, one vertex per distinct v/vt/vn triple."""
    V, VT, VN, F = [], [], [], []
    for line in open(src, errors='replace'):
        w = line.split()
        if not w:
            continue
        if w[0] == 'v':
            V.append([float(x) for x in w[1:4]])
        elif w[0] == 'vt':
            VT.append([float(x) for x in w[1:3]])
        elif w[0] == 'vn':
            VN.append([float(x) for x in w[1:4]])
        elif w[0] == 'f':
            c = [tuple(int(x) - 1 for x in t.split('/')) for t in w[1:]]
            F += [(c[0], c[i], c[i + 1]) for i in range(1, len(c) - 1)]
    key, verts, faces = {}, [], []
    for f in F:
        idx = []
        for x in f:
            if x not in key:
                key[x] = len(verts)
                verts.append(V[x[0]] + VN[x[2]] + VT[x[1]])
            idx.append(key[x])
        if len(set(idx)) == 3:
            faces.append(idx)
    props = [(n, 'f', None) for n in ('x', 'y', 'z', 'nx', 'ny', 'nz', 'u', 'v')]
    write_ply(dst, props, verts, faces)


def with_normals(src, dst):
    m = read_ply(src)
    verts = [r[:3] for r in m['vertex'][1]]
    faces = faces_of(m)
    n = [[0.0, 0.0, 0.0] for _ in verts]
    for t in faces:
        a, b, c = (verts[i] for i in t)
        u = [b[j] - a[j] for j in range(3)]
        v = [c[j] - a[j] for j in range(3)]
        x = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        for i in t:
            for j in range(3):
                n[i][j] += x[j]
    out = []
    for p, x in zip(verts, n):
        length = math.sqrt(sum(c * c for c in x))
        out.append(list(p) + ([c / length for c in x] if length > 0 else [0.0, 0.0, 1.0]))
    write_ply(dst, [(k, 'f', None) for k in ('x', 'y', 'z', 'nx', 'ny', 'nz')], out, faces)


def welded_float(src, dst):
    m = read_ply(src)
    props, rows = m['vertex']
    key, verts, remap = {}, [], []
    for r in rows:
        k = tuple(r)
        if k not in key:
            key[k] = len(verts)
            verts.append(r)
        remap.append(key[k])
    faces = [tuple(remap[i] for i in f) for f in faces_of(m)]
    faces = [f for f in faces if len(set(f)) == 3]
    write_ply(dst, [(n, 'f' if t == 'd' else t, None) for n, t, _ in props], verts, faces)


def to_obj(src, dst):
    m = read_ply(src)
    props, rows = m['vertex']
    names = [p[0] for p in props]
    n0 = names.index('nx') if 'nx' in names else -1
    t0 = names.index('s') if 's' in names else names.index('u')
    lines = ['v %.9g %.9g %.9g' % tuple(r[:3]) for r in rows]
    if n0 >= 0:
        lines += ['vn %.9g %.9g %.9g' % tuple(r[n0:n0 + 3]) for r in rows]
    lines += ['vt %.9g %.9g' % tuple(r[t0:t0 + 2]) for r in rows]
    form = '%d/%d/%d' if n0 >= 0 else '%d/%d'
    for f in faces_of(m):
        lines.append('f ' + ' '.join(form % ((i + 1,) * form.count('%d')) for i in f))
    open(dst, 'w').write('\n'.join(lines) + '\n')


def with_ids(src, dst):
    m = read_ply(src)
    props, rows = m['vertex']
    write_ply(dst, list(props) + [('psq_id', 'i', None)], [list(r) + [i] for i, r in enumerate(rows)], faces_of(m))


def errors(src, decoded, uv_bits):
    """Largest normal angle (degrees), texture coordinate error (in steps of
    2^-uv_bits) and colour difference between a mesh and its decoded copy."""
    a = read_ply(src)['vertex']
    b = read_ply(decoded)['vertex']
    an = [p[0] for p in a[0]]
    bn = [p[0] for p in b[0]]
    byid = {r[bn.index('psq_id')]: r for r in b[1]}
    angle = uv = colour = 0.0
    for i, r in enumerate(a[1]):
        d = byid[i]
        if 'nx' in an:
            x = r[an.index('nx'):an.index('nx') + 3]
            y = d[bn.index('nx'):bn.index('nx') + 3]
            lx = math.sqrt(sum(c * c for c in x))
            if lx > 0:
                dot = sum(p * q for p, q in zip(x, y)) / lx / math.sqrt(sum(c * c for c in y))
                angle = max(angle, math.degrees(math.acos(max(-1.0, min(1.0, dot)))))
        for n in ('u', 'v', 's', 't'):
            if n in an:
                uv = max(uv, abs(r[an.index(n)] - d[bn.index(n)]) * 2 ** uv_bits)
        for n in ('red', 'green', 'blue', 'alpha'):
            if n in an:
                colour = max(colour, abs(r[an.index(n)] - d[bn.index(n)]))
    return angle, uv, colour


def size(path):
    return os.path.getsize(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--psq', default='build/psq')
    ap.add_argument('--normal-bits', type=int, default=8)
    ap.add_argument('--uv-bits', type=int, default=10)
    ap.add_argument('--old-psq', help='a psq of format 10.0 (properties as zstd columns), for a column of its sizes')
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix='psq_attr_')
    inputs = []
    for name, src in [('bcn_epileptic', 'X/BCN_Epileptic.X'), ('duck', 'Collada/duck.dae'),
                      ('dwarf', 'COB/dwarf.cob'), ('faerie', 'MD2/faerie.md2'),
                      ('milktruck', 'glTF/CesiumMilkTruck/CesiumMilkTruck.gltf'), ('teapots', 'Collada/teapots.DAE'),
                      ('wuson', 'X/Testwuson.X')]:
        dst = os.path.join(tmp, name + '.ply')
        subprocess.run(['assimp', 'export', os.path.join(ASSIMP, src), dst, '-jiv', '-tri', '-ptv'], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        inputs.append(dst)
    split_obj(os.path.join(ASSIMP, 'OBJ/spider.obj'), os.path.join(tmp, 'spider.ply'))
    inputs.append(os.path.join(tmp, 'spider.ply'))
    for name in ('bunny', 'bunny_closed', 'diplodocus', 'fandisk', 'refined_elephant'):
        dst = os.path.join(tmp, name + '_normals.ply')
        with_normals(os.path.join(SHARED, 'meshes', name + '.ply'), dst)
        inputs.append(dst)
    welded_float(os.path.join(SHARED, 'inputs', 'fandisk.rich.ply'), os.path.join(tmp, 'fandisk_rich.ply'))
    inputs.append(os.path.join(tmp, 'fandisk_rich.ply'))

    old = ' psq 10.0 compact |' if args.old_psq else ''
    print('| mesh | vertices | attributes | Draco |' + old + ' psq compact | psq fast | compact / Draco | fast / Draco '
          '| normal error | uv error (steps) | colour error |')
    print('|---|---:|---|---:|' + ('---:|' if old else '') + '---:|---:|---:|---:|---:|---:|---:|')
    ratios = {'compact': [], 'fast': [], 'old': []}
    for src in sorted(inputs):
        name = os.path.basename(src)[:-4]
        m = read_ply(src)
        names = [p[0] for p in m['vertex'][0]]
        kinds = [k for k, n in (('normals', 'nx'), ('texcoords', 'u'), ('texcoords', 's'), ('colours', 'red'))
                 if n in names]
        draco_in = src
        if 'u' in names or 's' in names:
            draco_in = os.path.join(tmp, name + '.obj')
            to_obj(src, draco_in)
        drc = os.path.join(tmp, name + '.drc')
        subprocess.run(['draco_encoder', '-i', draco_in, '-o', drc, '-qp', '14', '-qn', '8', '-qt', '10', '-cl', '7'],
                       check=True, stdout=subprocess.DEVNULL)
        row = [name, str(len(m['vertex'][1])), ' '.join(kinds), str(size(drc))]
        if args.old_psq:
            out = os.path.join(tmp, name + '.old.psq')
            subprocess.run([args.old_psq, 'convert', '-q', '-f', '--profile', 'compact', '--bits', '14', src, out],
                           check=True)
            row.append(str(size(out)))
            ratios['old'].append(size(out) / size(drc))
        sizes = {}
        for profile in ('compact', 'fast'):
            out = os.path.join(tmp, name + '.' + profile + '.psq')
            subprocess.run([args.psq, 'convert', '-q', '-f', '--profile', profile, '--bits', '14', '--normal-bits',
                            str(args.normal_bits), '--uv-bits', str(args.uv_bits), src, out], check=True)
            sizes[profile] = size(out)
            ratios[profile].append(sizes[profile] / size(drc))
        row += [str(sizes['compact']), str(sizes['fast']), '%.3f' % (sizes['compact'] / size(drc)),
                '%.3f' % (sizes['fast'] / size(drc))]
        # The errors, through a copy with an exact vertex id (a column).
        ided = os.path.join(tmp, name + '.id.ply')
        with_ids(src, ided)
        psq_file = os.path.join(tmp, name + '.id.psq')
        back = os.path.join(tmp, name + '.back.ply')
        subprocess.run([args.psq, 'convert', '-q', '-f', '--bits', '14', '--normal-bits', str(args.normal_bits),
                        '--uv-bits', str(args.uv_bits), ided, psq_file], check=True)
        subprocess.run([args.psq, 'convert', '-q', '-f', psq_file, back], check=True)
        angle, uv, colour = errors(ided, back, args.uv_bits)
        row += ['%.3f°' % angle if 'normals' in kinds else '', '%.3f' % uv if 'texcoords' in kinds else '',
                '%g' % colour if 'colours' in kinds else '']
        print('| ' + ' | '.join(row) + ' |')
        sys.stdout.flush()
    print()
    for profile in ('compact', 'fast', 'old'):
        if ratios[profile]:
            print('median %s / Draco: %.3f' % (profile, statistics.median(ratios[profile])))


if __name__ == '__main__':
    main()
