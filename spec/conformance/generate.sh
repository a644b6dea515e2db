#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Regenerates the .psq conformance vectors of spec/psq-format.md (section
# 12) from meshes in tests/data and meshes written here, with the psq binary
# given as $1 (default: build/psq). Every valid vector NAME.psq comes with
# NAME.dump, the exact `psq dump` a conforming decoder yields, and a line in
# MANIFEST with the dump's SHA-256; every invalid vector has a line with the
# error it must produce and the byte offset of that error.
#
#   spec/conformance/generate.sh build/psq
#
# The encoder is deterministic: rerunning this on the same version of psq
# gives the same bytes (tests/conformance_test.cpp checks the vectors).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
psq="$(cd "$(dirname "${1:-$root/build/psq}")" && pwd)/$(basename "${1:-$root/build/psq}")"
data="$root/tests/data"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cd "$here"
rm -f ./*.psq ./*.dump MANIFEST

# A tetrahedron with one vertex and one face property of every type, a
# list face property, and an isolated vertex.
cat > "$tmp/props.ply" <<'PLY'
ply
format ascii 1.0
comment conformance: every property type
element vertex 5
property float x
property float y
property float z
property char c
property uchar uc
property short s
property ushort us
property int i
property uint ui
property float f
property double d
element face 4
property list uchar int vertex_indices
property list uchar float pairs
property int material
end_header
0 0 0 -128 0 -32768 0 -2147483648 0 -1.5 0.1
1 0 0 127 255 32767 65535 2147483647 4294967295 3.25 -1e300
0 1 0 -1 1 -1 1 -1 1 1e-30 2.5
0 0 1 0 128 0 32768 0 2147483648 -0 1e-300
5 5 5 1 2 3 4 5 6 7 8
3 0 2 1 6 0 0 0.5 0.5 1 1 7
3 0 1 3 0 -3
3 0 3 2 2 0.25 0.75 0
3 1 2 3 4 1 2 3 4 2
PLY

# An open 4x4 grid (borders on all sides).
{
  echo "ply"; echo "format ascii 1.0"; echo "element vertex 25"
  echo "property float x"; echo "property float y"; echo "property float z"
  echo "element face 32"; echo "property list uchar int vertex_indices"; echo "end_header"
  for y in 0 1 2 3 4; do for x in 0 1 2 3 4; do echo "$x $y 0"; done; done
  for y in 0 1 2 3; do for x in 0 1 2 3; do
    a=$((y * 5 + x)); echo "3 $a $((a + 1)) $((a + 6))"; echo "3 $a $((a + 6)) $((a + 5))"
  done; done
} > "$tmp/grid.ply"

# A UV sphere of 4 rings and 8 segments (48 triangles), for far_gates below.
python3 - > "$tmp/sphere.ply" <<'PY'
import math
rings, seg = 4, 8
v = [(0.0, 0.0, 1.0)]
for r in range(1, rings):
    t = math.pi * r / rings
    v += [(math.sin(t) * math.cos(2 * math.pi * k / seg), math.sin(t) * math.sin(2 * math.pi * k / seg), math.cos(t))
          for k in range(seg)]
v.append((0.0, 0.0, -1.0))
ring = lambda r, k: 1 + (r - 1) * seg + k % seg
f = [(0, ring(1, k), ring(1, k + 1)) for k in range(seg)]
for r in range(1, rings - 1):
    for k in range(seg):
        f += [(ring(r, k), ring(r + 1, k), ring(r + 1, k + 1)), (ring(r, k), ring(r + 1, k + 1), ring(r, k + 1))]
f += [(len(v) - 1, ring(rings - 1, k + 1), ring(rings - 1, k)) for k in range(seg)]
print("ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z" % len(v))
print("element face %d\nproperty list uchar int vertex_indices\nend_header" % len(f))
for p in v: print("%.6f %.6f %.6f" % p)
for t in f: print("3 %d %d %d" % t)
PY

# A curved 8x8 grid of double positions, jittered and with mixed
# diagonals (so that the encoder also chooses means), far from the origin on
# both sides: every coordinate has a magnitude of 2 or more, so that its
# order-preserving integer (spec 7.2) has a magnitude of 2^62 or more and
# the sum of any two of them overflows 64 bits. The means of spec 7.3
# (mid(), choices 3 and 4 and a start's third vertex) must be computed
# without that overflow.
python3 - > "$tmp/doubles.ply" <<'PY'
import math
n = 9
v = []
for j in range(n):
    for i in range(n):
        x = 1000.0 + 1.3 * i + 0.4 * math.sin(7.1 * i + 3.7 * j * j)
        y = -(2000.0 + 1.1 * j + 0.4 * math.cos(5.3 * i * i - 2.9 * j))
        z = 3.0 + 0.02 * (i * i + j * j) + 0.2 * math.sin(1.9 * i * j + i)
        v.append((x, y, z))
f = []
for j in range(n - 1):
    for i in range(n - 1):
        a = j * n + i
        if (3 * i + 5 * j) % 7 < 3:  # the other diagonal
            f += [(a, a + 1, a + n), (a + 1, a + n + 1, a + n)]
        else:
            f += [(a, a + 1, a + n + 1), (a, a + n + 1, a + n)]
print("ply\nformat ascii 1.0\nelement vertex %d\nproperty double x\nproperty double y\nproperty double z" % len(v))
print("element face %d\nproperty list uchar int vertex_indices\nend_header" % len(f))
for p in v: print("%.17g %.17g %.17g" % p)
for t in f: print("3 %d %d %d" % t)
PY

valid() {  # NAME INPUT [convert options...]
  local name="$1" input="$2"
  shift 2
  "$psq" convert "$input" "$name.psq" -q "$@"
  "$psq" dump "$name.psq" -o "$name.dump"
  echo "valid $name.psq $(sha256sum < "$name.dump" | cut -d' ' -f1)" >> MANIFEST
}

valid cube_11bit "$data/cube_quads.obj" --bits 11
valid grid_borders "$tmp/grid.ply" --bits 8
valid spider_16bit "$data/spider.ply"
valid spider_lossless "$data/spider.ply" --lossless
valid nonmanifold_wrap "$data/nonmanifold_wrap.ply" --bits 12
valid max_export_chunks "$data/max_export_nm.ply" --bits 14 --chunk 256
valid properties_lossless "$tmp/props.ply" --lossless
valid properties_1bit "$tmp/props.ply" --bits 1
valid doubles_lossless "$tmp/doubles.ply" --lossless
# The fast profile (spec 13).
valid fast_spider_16bit "$data/spider.ply" --profile fast
valid fast_spider_lossless "$data/spider.ply" --lossless --profile fast
valid fast_grid_borders "$tmp/grid.ply" --bits 8 --profile fast
valid fast_nonmanifold_wrap "$data/nonmanifold_wrap.ply" --bits 12 --profile fast
valid fast_max_export_chunks "$data/max_export_nm.ply" --bits 14 --chunk 256 --profile fast
valid fast_properties_lossless "$tmp/props.ply" --lossless --profile fast
# Coded attributes (spec 8.3): normals (one of them zero), texture
# coordinates named s t with a seam, and RGBA colours, quantized and
# lossless, in both profiles; and a real model's normals and texture
# coordinates.
valid attributes_8bit "$data/attributes.ply" --bits 12 --normal-bits 8 --uv-bits 10
valid attributes_lossless "$data/attributes.ply" --lossless
valid fast_attributes_8bit "$data/attributes.ply" --bits 12 --normal-bits 8 --uv-bits 10 --profile fast
valid fast_attributes_lossless "$data/attributes.ply" --lossless --profile fast
valid spider_attributes "$data/spider_attributes.ply" --bits 14 --normal-bits 10 --uv-bits 12
# Spec 8.4: a fan of 4200 triangles around vertex 0, whose normal settles
# 4096 records after its introduction, before its last triangle comes.
awk 'BEGIN {
  n = 4200; pi = atan2(0, -1)
  print "ply"; print "format ascii 1.0"; print "element vertex " n + 1
  print "property float x"; print "property float y"; print "property float z"
  print "property float nx"; print "property float ny"; print "property float nz"
  print "element face " n; print "property list uchar int vertex_indices"; print "end_header"
  print "0 0 0 0 0 1"
  for (i = 0; i < n; ++i) {
    a = 2 * pi * i / n; z = 0.1 * sin(7 * a)
    printf "%.6f %.6f %.6f %.6f %.6f %.6f\n", cos(a), sin(a), z, 0.3 * cos(a), 0.3 * sin(a), 1
  }
  for (i = 0; i < n; ++i) printf "3 0 %d %d\n", 1 + i, 1 + (i + 1) % n
}' > "$tmp/fan.ply"
valid fan_normals "$tmp/fan.ply" --bits 12 --normal-bits 6
valid fast_spider_attributes "$data/spider_attributes.ply" --bits 14 --normal-bits 10 --uv-bits 12 --profile fast
# Corner attributes (spec 8.5): the spider as its OBJ has it, positions
# welded, normals and texture coordinates per corner; in chunks of 1 KiB
# (corner normals settle at chunk ends) and segments, in both profiles.
# A fan of 4200 triangles with uchar colours per vertex, normals per
# corner and a material per triangle (the rotation kept): the centre's
# normal settles by the 4096-record bound.
awk 'BEGIN {
  n = 4200; pi = atan2(0, -1)
  print "ply"; print "format ascii 1.0"; print "element vertex " n + 1
  print "property float x"; print "property float y"; print "property float z"
  print "property uchar red"; print "property uchar green"; print "property uchar blue"
  print "element face " n; print "property list uchar int vertex_indices"
  print "property list uchar float corner_normals"; print "property uchar material"; print "end_header"
  print "0 0 0 255 0 0"
  for (j = 0; j < n; ++j) {
    a = 2 * pi * j / n
    printf "%.6f %.6f %.6f %d 128 7\n", cos(a), sin(a), 0.1 * sin(7 * a), j % 256
  }
  for (i = 0; i < n; ++i) {
    j = (i + 1) % n; ai = 2 * pi * i / n; aj = 2 * pi * j / n
    printf "3 0 %d %d 9 0 0 1 %.4f %.4f 1 %.4f %.4f 1 %d\n", 1 + i, 1 + j, 0.3 * cos(ai), 0.3 * sin(ai), 0.3 * cos(aj), 0.3 * sin(aj), i % 3
  }
}' > "$tmp/corner_fan.ply"
valid corner_fan "$tmp/corner_fan.ply" --bits 12 --normal-bits 6
# A fan of 60 triangles whose centre has many values per corner: texture
# coordinates that come back after 5 triangles (wedge symbols up to 4),
# then a new one a triangle (the ninth evicts the least recent); normals
# that alternate between two, then a new one a triangle (evicted while
# they wait); a texture seam where the fan closes.
awk 'BEGIN {
  n = 60; pi = atan2(0, -1)
  print "ply"; print "format ascii 1.0"; print "element vertex " n + 1
  print "property float x"; print "property float y"; print "property float z"
  print "element face " n; print "property list uchar int vertex_indices"
  print "property list uchar float corner_normals"; print "property list uchar float corner_uv"; print "end_header"
  print "0 0 0"
  for (j = 0; j < n; ++j) { a = 2 * pi * j / n; printf "%.6f %.6f %.6f\n", cos(a), sin(a), 0.1 * sin(3 * a) }
  for (i = 0; i < n; ++i) {
    j = (i + 1) % n; ai = 2 * pi * i / n; aj = 2 * pi * j / n
    if (i < 30) { cu = (i % 5) / 8; cv = 0.5; ny = (i % 2) * 0.5; nx = 0 } else { cu = i / 64; cv = 0.25; ny = 0; nx = (i - 30) / 30 }
    uj = j / 64; if (i == n - 1) uj = 1
    printf "3 0 %d %d 9 %.4f %.4f 1 %.4f %.4f 1 %.4f %.4f 1 6 %.6f %.6f %.6f 1 %.6f 1\n", 1 + i, 1 + j, nx, ny, 0.3 * cos(ai), 0.3 * sin(ai), 0.3 * cos(aj), 0.3 * sin(aj), cu, cv, i / 64, uj
  }
}' > "$tmp/corner_wedges.ply"
valid corner_wedges "$tmp/corner_wedges.ply" --bits 12 --normal-bits 8 --uv-bits 10
valid fast_corner_wedges "$tmp/corner_wedges.ply" --bits 12 --normal-bits 8 --uv-bits 10 --profile fast
valid segments_spider_corners "$data/spider.obj" --bits 14 --normal-bits 10 --uv-bits 12 --segment 300 --chunk 1024
valid fast_segments_spider_corners "$data/spider.obj" --bits 14 --normal-bits 10 --uv-bits 12 --segment 300 --chunk 1024 --profile fast
# Segments (spec 4.6, 4.7): a segment record every 300 triangles of the
# spider's 1368 (four records), quantized, lossless and with attributes;
# every 4 triangles of nonmanifold_wrap's 12 (two records, whose states
# hold vertices that re-appear later), in both profiles.
valid segments_spider "$data/spider.ply" --segment 300
valid segments_spider_lossless "$data/spider.ply" --lossless --segment 300
valid segments_spider_attributes "$data/spider_attributes.ply" --bits 14 --normal-bits 10 --uv-bits 12 --segment 300
valid segments_nonmanifold_wrap "$data/nonmanifold_wrap.ply" --bits 12 --segment 4
valid fast_segments_spider "$data/spider.ply" --segment 300 --profile fast
valid fast_segments_spider_lossless "$data/spider.ply" --lossless --segment 300 --profile fast
valid fast_segments_spider_attributes "$data/spider_attributes.ply" --bits 14 --normal-bits 10 --uv-bits 12 --segment 300 --profile fast
valid fast_segments_nonmanifold_wrap "$data/nonmanifold_wrap.ply" --bits 12 --segment 4 --profile fast
# Written to a pipe: the same bytes as to a file (the encoder never seeks).
"$psq" convert - - --to psq --bits 10 < "$data/spider.ply" > spider_pipe.psq
"$psq" dump spider_pipe.psq -o spider_pipe.dump
echo "valid spider_pipe.psq $(sha256sum < spider_pipe.dump | cut -d' ' -f1)" >> MANIFEST

# Far gates of every kind (spec 6.2.1): the converter grows one region at a
# time, so psq_interleave (codec/tools/interleave.cpp) interleaves the
# records of 20 copies of the sphere instead; the stream names far gates by
# recency rank, by departure point and offset, and by raw slot.
"$psq" convert "$tmp/sphere.ply" "$tmp/sphere.psq" -q --lossless
"$(dirname "$psq")/psq_interleave" "$tmp/sphere.psq" far_gates.psq --copies 20 --seed 5 --bits 12 > /dev/null
"$psq" dump far_gates.psq -o far_gates.dump
echo "valid far_gates.psq $(sha256sum < far_gates.dump | cut -d' ' -f1)" >> MANIFEST

invalid() {  # NAME CODE OFFSET (the file is already written)
  echo "invalid $1.psq $2 $3" >> MANIFEST
}
src=cube_11bit.psq
size=$(stat -c %s "$src")
# Spec 3.1: the varint at byte offset $2 of file $1, as "VALUE LENGTH".
varint() {
  python3 -c 'import sys
b = open(sys.argv[1], "rb").read(); at = int(sys.argv[2]); v = 0; n = 0
while True:
    v |= (b[at + n] & 0x7f) << (7 * n); n += 1
    if not b[at + n - 1] & 0x80: break
print(v, n)' "$1" "$2"
}
read -r hlen hvar < <(varint "$src" 12)
payload=$((12 + hvar))     # where the header payload starts
chunk=$((payload + hlen + 4))  # the first chunk's tag
# Not .psq at all.
printf 'PLY\n' > bad_magic.psq; invalid bad_magic unknown_format 0
# A major version other than 1 (2): unsupported (spec 4.2, 11).
{ head -c 8 "$src"; printf '\x02'; tail -c +10 "$src"; } > bad_version.psq; invalid bad_version unsupported 8
# An unknown flag.
{ head -c 11 "$src"; printf '\x80'; tail -c +13 "$src"; } > bad_flags.psq; invalid bad_flags unsupported 10
# A header payload of 2^28 bytes (a five-byte varint).
{ head -c 12 "$src"; printf '\x80\x80\x80\x80\x01'; tail -c +$((payload + 1)) "$src"; } > bad_header_length.psq
invalid bad_header_length limit 12
# The payload length in a longer form than needed (its last byte gets the
# continuation bit and a 0x00 byte follows): a malformed varint.
python3 -c 'import sys
b = open(sys.argv[1], "rb").read(); n = int(sys.argv[2])
v = bytearray(b[12:12 + n]); v[-1] |= 0x80
open(sys.argv[3], "wb").write(b[:12] + bytes(v) + b"\x00" + b[12 + n:])' "$src" "$hvar" bad_varint.psq
invalid bad_varint bad_header 12
# A flipped bit in the header payload: its checksum fails.
{ head -c 20 "$src"; printf '\x01'; tail -c +22 "$src"; } > bad_header_checksum.psq
invalid bad_header_checksum checksum $((payload + hlen))
# Cut inside the first chunk.
head -c $((chunk + 30)) "$src" > truncated_chunk.psq
invalid truncated_chunk truncated $((chunk + 30))
# Cut inside the end record's checksum (the error names where the input ends).
head -c $((size - 2)) "$src" > truncated_end.psq
invalid truncated_end truncated $((size - 2))
# A flipped bit in the first chunk's records: its checksum fails.
at=$((chunk + 1))
for field in records vertices triangles conn prop raw attr; do
  read -r value len < <(varint "$src" $at)
  declare "$field=$value"
  at=$((at + len))
done
crc_at=$((at + conn + prop + attr))
{ head -c $((at + 1)) "$src"; printf '\xff'; tail -c +$((at + 3)) "$src"; } > bad_chunk_checksum.psq
invalid bad_chunk_checksum checksum $crc_at
# An unknown chunk tag.
{ head -c $chunk "$src"; printf 'Z'; tail -c +$((chunk + 2)) "$src"; } > bad_chunk_tag.psq
invalid bad_chunk_tag bad_header $chunk
# Trailing bytes after the end record.
{ cat "$src"; printf '\x00'; } > trailing_data.psq; invalid trailing_data bad_header $size

# Segments (spec 4.6, 4.7), from segments_spider.psq. The script below
# walks a stream's blocks, and makes the checksums that a change breaks
# right again, so that each vector breaks one rule only.
cat > "$tmp/segments.py" <<'PY'
import os, subprocess, sys, tempfile

def crc32c(data, crc=0):
    # Spec 3.3: CRC-32C (Castagnoli), reflected, polynomial 0x82F63B78.
    crc ^= 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ (0x82F63B78 & -(crc & 1))
    return crc ^ 0xFFFFFFFF

def varint(b, at):  # spec 3.1: (value, length)
    v = n = 0
    while True:
        v |= (b[at + n] & 0x7F) << (7 * n)
        n += 1
        if not b[at + n - 1] & 0x80:
            return v, n

def put_varint(v):
    out = bytearray()
    while True:
        out.append((v & 0x7F) | (0x80 if v > 0x7F else 0))
        v >>= 7
        if not out[-1] & 0x80:
            return bytes(out)

def blocks(b):
    # The header's checksum field, then every block (spec 4.3 to 4.7) as
    # (tag, start, end).
    hlen, hv = varint(b, 12)
    at = 12 + hv + hlen + 4
    out = [('H', at - 4, at)]
    while True:
        tag, start = chr(b[at]), at
        at += 1
        if tag == 'C':
            f = []
            for _ in range(7):
                v, n = varint(b, at)
                f.append(v)
                at += n
            at += f[3] + f[4] + f[6] + 4
        elif tag == 'S':
            z, n = varint(b, at)
            at += n
            at += varint(b, at)[1] + z + 4
        elif tag == 'I':
            c, n = varint(b, at)
            at += n
            for _ in range(3 * c):
                at += varint(b, at)[1]
            at += 4
        elif tag == 'E':
            out.append((tag, start, len(b)))
            return out
        else:
            raise SystemExit('unexpected tag at byte %d' % start)
        out.append((tag, start, at))

def fix_stream_checksum(b):
    # Spec 4.5: the header's and every block's checksum fields, then the
    # end record before its checksum.
    bl = blocks(b)
    chain = b''.join(bytes(b[e - 4:e]) for t, s, e in bl if t != 'E')
    chain += bytes(b[bl[-1][1]:len(b) - 4])
    b[-4:] = crc32c(chain).to_bytes(4, 'little')

def zstd(args, data):
    with tempfile.TemporaryDirectory() as d:  # a file, so that the frame declares its size
        path = os.path.join(d, 'in')
        open(path, 'wb').write(data)
        return subprocess.run(['zstd', '-q', '-c'] + args + [path], check=True, capture_output=True).stdout

cmd, src, dst = sys.argv[1:4]
b = bytearray(open(src, 'rb').read())
bl = blocks(b)
segs = [(s, e) for t, s, e in bl if t == 'S']
index = [(s, e) for t, s, e in bl if t == 'I'][0]
def state_at(s):  # (packed size, raw size, offset of the state block)
    z, n1 = varint(b, s + 1)
    u, n2 = varint(b, s + 1 + n1)
    return z, u, s + 1 + n1 + n2
if cmd == 'remove':
    # The first segment record cut out: the chunk after it stands where
    # the record must.
    s, e = segs[0]
    b[s:e] = b''
    print(s)
elif cmd == 'flip':
    # A bit flipped in the first state block: the record's checksum.
    z, u, at = state_at(segs[0][0])
    b[at + z // 2] ^= 0x01
    print(at + z)
elif cmd == 'state':
    # The last segment record's state with its records count one higher
    # (it still parses), compressed again, with the record's checksum,
    # the index offset and the stream checksum made right: the block is
    # not the decoder's state.
    s, e = segs[-1]
    z, u, at = state_at(s)
    raw = bytearray(zstd(['-d'], bytes(b[at:at + z])))
    assert len(raw) == u
    records, n = varint(raw, 0)
    assert len(put_varint(records + 1)) == n
    raw[:n] = put_varint(records + 1)
    packed = zstd(['-19', '--no-check'], bytes(raw))
    rec = b'S' + put_varint(len(packed)) + put_varint(len(raw)) + packed
    b[s:e] = rec + crc32c(rec).to_bytes(4, 'little')
    b[-12:-4] = [x for t, x, y in blocks(b) if t == 'I'][0].to_bytes(8, 'little')
    fix_stream_checksum(b)
    print(s + len(rec) - len(packed))
elif cmd == 'index':
    # The vertex count of the index's first entry one higher, with the
    # index's checksum and the stream checksum made right.
    s, e = index
    at = s + 1 + varint(b, s + 1)[1]
    at += varint(b, at)[1]
    v, n = varint(b, at)
    assert len(put_varint(v + 1)) == n
    b[at:at + n] = put_varint(v + 1)
    b[e - 4:e] = crc32c(bytes(b[s:e - 4])).to_bytes(4, 'little')
    fix_stream_checksum(b)
    print(s)
else:
    raise SystemExit('unknown command ' + cmd)
open(dst, 'wb').write(b)
PY
seg=segments_spider.psq
# A segment record cut out: the chunk after it is refused (spec 4.3).
invalid segment_removed bad_header "$(python3 "$tmp/segments.py" remove $seg segment_removed.psq)"
# A flipped bit in a state block: the segment record's checksum (spec 4.6).
invalid bad_segment_checksum checksum "$(python3 "$tmp/segments.py" flip $seg bad_segment_checksum.psq)"
# A state block that parses but is not the decoder's state (spec 4.6).
invalid segment_state_differs bad_value "$(python3 "$tmp/segments.py" state $seg segment_state_differs.psq)"
# An index entry that is not its segment record's (spec 4.7).
invalid index_entry_differs bad_header "$(python3 "$tmp/segments.py" index $seg index_entry_differs.psq)"
echo "wrote $(grep -c . MANIFEST) vectors to $here"
