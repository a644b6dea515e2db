# SPDX-License-Identifier: Apache-2.0
"""psq.open: the processing sequence chunk by chunk, in bounded memory."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import psq
from conftest import canonical, grid_mesh


def test_chunks_make_up_the_mesh(tmp_path):
    p, f = grid_mesh(30, 20)
    path = tmp_path / "m.psq"
    psq.write(path, p, f, lossless=True, vertex_properties={"w": np.arange(len(p), dtype=np.uint32)})
    whole = psq.read(path)
    positions, faces, weights, finalized, ops = [], [], [], [], []
    with psq.open(path, chunk_triangles=100) as stream:
        assert stream.header["lossless"] and stream.header["position_type"] == "float"
        for chunk in stream:
            assert chunk.vertex_start == sum(len(x) for x in positions)
            assert len(chunk.faces) <= 100 and len(chunk.positions) <= 100
            assert (chunk.reappears == -1).all()  # a manifold mesh: no cut vertex
            positions.append(chunk.positions)
            faces.append(chunk.faces)
            weights.append(chunk.vertex_properties["w"])
            finalized.append(chunk.finalized)
            ops.append(chunk.ops)
        stats = stream.stats
    positions, faces = np.concatenate(positions), np.concatenate(faces)
    assert canonical(positions, faces) == canonical(p, f)
    # Vertices stream in the order psq.read numbers them.
    np.testing.assert_array_equal(positions, whole.positions)
    np.testing.assert_array_equal(np.concatenate(weights), whole.vertex_properties["w"])
    # Every vertex is finalized once, after its last use.
    fin = np.concatenate(finalized)
    assert sorted(fin.tolist()) == list(range(len(p)))
    last_use = np.zeros(len(p), dtype=np.int64)
    for t, tri in enumerate(faces):
        last_use[tri] = t
    # The ops: one start for one component; the op histogram as psq.info counts it.
    ops = np.concatenate(ops)
    counts = {name: int((ops == i).sum()) for i, name in enumerate(psq.OPS)}
    assert counts == psq.info(path)["ops"]
    assert stats["triangles"] == len(f)


def test_new_and_final_masks_mark_first_and_last_use(tmp_path):
    p, f = grid_mesh(12)
    seen, faces, final = set(), [], []
    with psq.open(psq.encode(p, f, lossless=True), chunk_triangles=7) as stream:
        for c in stream:
            for tri, new, fin in zip(c.faces.tolist(), c.new_mask.tolist(), c.final_mask.tolist()):
                for k in range(3):
                    assert bool(new >> k & 1) == (tri[k] not in seen)
                    seen.add(tri[k])
                faces.append(tri)
                final.append(fin)
    later = set()
    for tri, fin in zip(reversed(faces), reversed(final)):
        for k in range(3):
            assert bool(fin >> k & 1) == (tri[k] not in later)
        later.update(tri)


def test_iteration_after_close_stops():
    p, f = grid_mesh(6)
    s = psq.open(psq.encode(p, f))
    s.close()
    assert list(s) == []


# The mesh (about 12 MB as arrays) is streamed in chunks of at most 2048
# triangles by a fresh interpreter; its peak resident memory may grow by
# much less than the mesh (the decoder keeps the processing boundary of a
# grid, a row of vertices).
STREAM_SCRIPT = textwrap.dedent("""
    import sys
    import psq
    def status_kb(field):  # VmRSS: resident now; VmHWM: the peak (of this process image, unlike ru_maxrss)
        with open("/proc/self/status") as f:
            return next(int(l.split()[1]) for l in f if l.startswith(field + ":"))
    before = status_kb("VmRSS")
    budget = 2048 * (12 + 1 + 1 + 1 + 1) + 2048 * (12 + 8 + 4)  # bytes of one chunk's arrays, at most
    triangles = chunks = 0
    largest = 0
    with psq.open(sys.argv[1], chunk_triangles=2048) as stream:
        for chunk in stream:
            assert chunk.nbytes <= budget, (chunk.nbytes, budget)
            largest = max(largest, chunk.nbytes)
            triangles += len(chunk.faces)
            chunks += 1
    peak = status_kb("VmHWM")
    print(triangles, chunks, largest, max(0, peak - before))
""")


def test_streams_a_mesh_larger_than_its_memory_budget(tmp_path):
    p, f = grid_mesh(700, 360)  # 502,000 triangles, 252,000 vertices
    path = tmp_path / "big.psq"
    psq.write(path, p, f, bits=16)
    mesh_bytes = p.nbytes + f.nbytes
    r = subprocess.run([sys.executable, "-c", STREAM_SCRIPT, str(path)], capture_output=True, text=True,
                       timeout=600, env=dict(os.environ))
    assert r.returncode == 0, r.stderr
    triangles, chunks, largest, growth_kb = map(int, r.stdout.split())
    assert triangles == len(f)
    assert chunks >= len(f) // 2048
    assert largest * 20 < mesh_bytes  # each chunk is a small part of the mesh
    assert growth_kb * 1024 < mesh_bytes / 2, (growth_kb, mesh_bytes)


def test_header_and_stats_stay_readable_after_close(tmp_path):
    p, f = grid_mesh(8)
    path = tmp_path / "m.psq"
    psq.write(path, p, f)
    stream = psq.open(path, chunk_triangles=10)
    next(stream)
    stream.close()
    assert stream.header["bits"] == 16
    assert 0 < stream.stats["triangles"] <= len(f)
    assert list(stream) == []
    stream.close()  # twice is fine
    reader = psq._psq.Reader(str(path), True)
    reader.close()
    assert reader.next(10) is None and reader.stats()["triangles"] == 0
