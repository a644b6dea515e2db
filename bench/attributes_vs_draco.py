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
#   texture coordinate), and the spider OBJ split the same way; then
#   welded into an OBJ as artists' tools write them (one `v` per distinct
#   position, `vt` and `vn` indexed per corner), which both encoders read:
#   psq codes its normals and texture coordinates per corner (spec 8.5);
# - shared meshes (../shared/data) with area-weighted vertex normals, as a
#   scanner's software writes them;
# - fandisk.rich.ply (normals and uchar colours, synthetic), welded and
#   made float.
# Draco reads the same OBJ when the mesh has texture coordinates (its PLY
# reader drops them) and the same PLY otherwise; it runs as
# `draco_encoder -qp 14 -qn 8 -qt 10 -cl 7`, psq as
# `psq convert --bits 14 --normal-bits N --uv-bits M --profile P`.
# Needs: draco_encoder (Debian package draco), assimp (assimp-utils),
# /usr/share/assimp/models (assimp-testmodels).
import argparse
import json
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
    V, VT, VN, polygons = read_obj(src)
    F = []
    for p in polygons:
        c = [tuple(x) for x in p]
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


def to_obj(src, dst, texcoords=True, normals=True):
    """A split PLY as a welded OBJ: one v per distinct position, vt and vn
    in index spaces of their own, faces that weld degenerate dropped;
    without the texture coordinates or the normals when asked."""
    m = read_ply(src)
    props, rows = m['vertex']
    names = [p[0] for p in props]
    n0 = names.index('nx') if 'nx' in names and normals else -1
    t0 = names.index('s') if 's' in names else names.index('u')
    spaces = [({}, []), ({}, []), ({}, [])]

    def index(space, key):
        d, out = spaces[space]
        if key not in d:
            d[key] = len(out)
            out.append(key)
        return d[key] + 1

    corner = [(index(0, tuple(r[:3])), index(1, tuple(r[t0:t0 + 2])),
               index(2, tuple(r[n0:n0 + 3])) if n0 >= 0 else 0) for r in rows]
    lines = ['v %.9g %.9g %.9g' % p for p in spaces[0][1]]
    lines += ['vt %.9g %.9g' % t for t in spaces[1][1]] if texcoords else []
    lines += ['vn %.9g %.9g %.9g' % n for n in spaces[2][1]]
    for f in faces_of(m):
        c = [corner[i] for i in f]
        if len({x[0] for x in c}) == 3:
            if not texcoords:
                c = [(x[0], x[2]) if n0 >= 0 else (x[0],) for x in c]
                lines.append('f ' + ' '.join(('%d//%d' if n0 >= 0 else '%d') % x for x in c))
            else:
                lines.append('f ' + ' '.join(('%d/%d/%d' if n0 >= 0 else '%d/%d') % x[:3 if n0 >= 0 else 2] for x in c))
    open(dst, 'w').write('\n'.join(lines) + '\n')


def read_obj(path):
    V, VT, VN, F = [], [], [], []
    for line in open(path, errors='replace'):
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
            F.append([[int(x) - 1 if x else -1 for x in (t.split('/') + ['', ''])[:3]] for t in w[1:]])
    return V, VT, VN, F


def obj_errors(src, decoded, origin, step, uv_bits):
    """Largest corner normal angle (degrees) and texture coordinate error
    (steps of 2^-uv_bits) between an OBJ and its decoded copy: corners
    matched by their positions' grid points, faces by their corners'."""
    a, b = read_obj(src), read_obj(decoded)

    def cell(p):
        return tuple(int(math.floor((p[i] - origin[i]) / step + 0.5)) for i in range(3))

    def faces(m):
        out = {}
        for f in m[3]:
            key = tuple(sorted(cell(m[0][c[0]]) for c in f))
            out.setdefault(key, []).append({cell(m[0][c[0]]): c for c in f})
        return out

    fa, fb = faces(a), faces(b)
    angle = uv = 0.0
    for key, list_a in fa.items():
        for ca in list_a:
            best = None
            for cb in fb.get(key, []):
                ang = err = 0.0
                for g, x in ca.items():
                    y = cb[g]
                    if x[1] >= 0:
                        err = max(err, max(abs(p - q) for p, q in zip(a[1][x[1]], b[1][y[1]])) * 2 ** uv_bits)
                    if x[2] >= 0:
                        n, m = a[2][x[2]], b[2][y[2]]
                        ln = math.sqrt(sum(c * c for c in n)) * math.sqrt(sum(c * c for c in m))
                        if ln > 0:
                            dot = sum(p * q for p, q in zip(n, m)) / ln
                            ang = max(ang, math.degrees(math.acos(max(-1.0, min(1.0, dot)))))
                if best is None or (err, ang) < best:
                    best = (err, ang)
            if best is None:
                raise SystemExit('%s: a face of %s is missing' % (decoded, src))
            uv, angle = max(uv, best[0]), max(angle, best[1])
    return angle, uv


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


def textured_models(tmp):
    """The textured models as split PLYs written to tmp (one vertex per
    distinct position, normal and texture coordinate): their paths."""
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
    return inputs


def size(path):
    return os.path.getsize(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--psq', default='build/psq')
    ap.add_argument('--normal-bits', type=int, default=8)
    ap.add_argument('--uv-bits', type=int, default=10)
    ap.add_argument('--old-psq', help='a psq of format 10.0 (properties as zstd columns), for a column of its sizes')
    ap.add_argument('--parts', action='store_true',
                    help='also the textured models\' bytes by part: positions, texture coordinates, normals')
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix='psq_attr_')
    inputs = textured_models(tmp)
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
        textured = 'u' in names or 's' in names
        if textured:
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
                            str(args.normal_bits), '--uv-bits', str(args.uv_bits), draco_in, out], check=True)
            sizes[profile] = size(out)
            ratios[profile].append(sizes[profile] / size(drc))
        row += [str(sizes['compact']), str(sizes['fast']), '%.3f' % (sizes['compact'] / size(drc)),
                '%.3f' % (sizes['fast'] / size(drc))]
        if textured:
            back = os.path.join(tmp, name + '.back.obj')
            subprocess.run([args.psq, 'convert', '-q', '-f', os.path.join(tmp, name + '.compact.psq'), back],
                           check=True)
            info = json.loads(subprocess.run([args.psq, 'info', '--json', os.path.join(tmp, name + '.compact.psq')],
                                             check=True, capture_output=True).stdout)
            angle, uv = obj_errors(draco_in, back, info['bbox']['min'], info['psq']['step'], args.uv_bits)
            row += ['%.3f°' % angle if 'normals' in kinds else '', '%.3f' % uv, '']
            print('| ' + ' | '.join(row) + ' |')
            sys.stdout.flush()
            continue
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
    if args.parts:
        # Each part is the file with it less the file without (the
        # adaptive back-end; the same welded OBJ for both coders).
        print()
        print('| mesh | psq positions | Draco positions | psq texcoords | Draco texcoords | psq normals | Draco normals |')
        print('|---|---:|---:|---:|---:|---:|---:|')
        for src in sorted(inputs):
            name = os.path.basename(src)[:-4]
            names = [p[0] for p in read_ply(src)['vertex'][0]]
            if not ('u' in names or 's' in names):
                continue
            sizes = {}
            for part, (tc, nm) in (('p', (False, False)), ('t', (True, False)), ('n', (False, True))):
                obj = os.path.join(tmp, name + '.' + part + '.obj')
                to_obj(src, obj, tc, nm)
                drc, out = obj[:-4] + '.drc', obj[:-4] + '.psq'
                subprocess.run(['draco_encoder', '-i', obj, '-o', drc, '-qp', '14', '-qn', '8', '-qt', '10', '-cl', '7'],
                               check=True, stdout=subprocess.DEVNULL)
                subprocess.run([args.psq, 'convert', '-q', '-f', '--profile', 'compact', '--bits', '14', '--normal-bits',
                                str(args.normal_bits), '--uv-bits', str(args.uv_bits), obj, out], check=True)
                sizes[part] = (size(out), size(drc))
            row = [name, sizes['p'][0], sizes['p'][1], sizes['t'][0] - sizes['p'][0], sizes['t'][1] - sizes['p'][1]]
            row += [sizes['n'][0] - sizes['p'][0], sizes['n'][1] - sizes['p'][1]] if 'nx' in names else ['', '']
            print('| ' + ' | '.join(str(x) for x in row) + ' |')


if __name__ == '__main__':
    main()
