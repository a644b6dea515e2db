# SPDX-License-Identifier: Apache-2.0
"""Arrays handed over without copies, and the GIL released while psq works."""

import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import psq
from conftest import canonical, grid_mesh


def is_psq_buffer(a: np.ndarray) -> bool:
    """The array views a buffer psq filled (a capsule owning the C++ vector), not a copy."""
    return not a.flags.owndata and type(a.base).__name__ == "PyCapsule"


@pytest.mark.parametrize("ext", ["psq", "ply"])
def test_read_hands_over_its_buffers(tmp_path, ext):
    p, f = grid_mesh(10)
    path = tmp_path / f"m.{ext}"
    psq.write(path, p, f, vertex_properties={"q": np.arange(len(p), dtype=np.float32)},
              face_properties={"l": psq.ListProperty(np.ones(len(f), np.uint32), np.arange(len(f), dtype=np.int32))})
    m = psq.read(path)
    for a in (m.positions, m.faces, m.vertex_properties["q"], m.face_properties["l"].counts,
              m.face_properties["l"].values):
        assert is_psq_buffer(a)
    m.positions[0, 0] = 5.0  # the arrays are the caller's to change
    assert m.positions[0, 0] == 5.0


def test_decode_fast_path_hands_over_its_buffers():
    p, f = grid_mesh(10)
    m = psq.decode(psq.encode(p, f))
    assert is_psq_buffer(m.positions) and is_psq_buffer(m.faces)
    assert m.positions.flags.c_contiguous and m.positions.shape == (len(p), 3)


def test_stream_chunks_hand_over_their_buffers():
    p, f = grid_mesh(10)
    with psq.open(psq.encode(p, f), chunk_triangles=50) as s:
        chunk = next(iter(s))
    for a in (chunk.positions, chunk.faces, chunk.ops, chunk.finalized):
        assert is_psq_buffer(a)


def test_buffers_outlive_the_mesh_object():
    p, f = grid_mesh(10)
    positions = psq.decode(psq.encode(p, f, lossless=True)).positions
    import gc
    gc.collect()
    assert sorted(map(tuple, positions.tolist())) == sorted(map(tuple, p.tolist()))


def test_two_threads_decode_two_meshes():
    meshes = [grid_mesh(60, 40), grid_mesh(50, 70, wave=0.1)]
    data = [psq.encode(p, f) for p, f in meshes]
    results = [None, None]
    errors = []

    def work(i):
        try:
            for _ in range(3):
                results[i] = psq.decode(data[i])
        except Exception as e:  # reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for (p, f), m in zip(meshes, results):
        assert len(m.faces) == len(f) and len(m.positions) == len(p)


# Two reader threads block inside psq.read on two named pipes at the same
# time; only the main thread, running Python, can feed the pipes. If
# psq.read held the GIL while it waits for input, the main thread could
# never run and the script would hang: the parent's timeout (a guard
# against a hang, not a measurement) then fails the test. No timing is
# asserted.
GIL_SCRIPT = textwrap.dedent("""
    import os, sys, threading
    import numpy as np
    import psq
    from conftest import grid_mesh
    tmp = sys.argv[1]
    meshes = [grid_mesh(40), grid_mesh(30, 50)]
    data = [psq.encode(p, f, lossless=True) for p, f in meshes]
    fifos = [os.path.join(tmp, "a.fifo"), os.path.join(tmp, "b.fifo")]
    for path in fifos:
        os.mkfifo(path)
    results = [None, None]
    inside = [threading.Event(), threading.Event()]

    def reader(i):
        inside[i].set()
        results[i] = psq.read(fifos[i])  # blocks in C++ until the main thread writes

    threads = [threading.Thread(target=reader, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for e in inside:
        e.wait()
    # Both readers are in (or about to enter) psq.read; feed both pipes in
    # interleaved halves, so that both are inside it at once.
    pipes = [open(path, "wb") for path in fifos]
    for i in range(2):
        pipes[i].write(data[i][: len(data[i]) // 2])
        pipes[i].flush()
    for i in range(2):
        pipes[i].write(data[i][len(data[i]) // 2:])
        pipes[i].close()
    for t in threads:
        t.join()
    for (p, f), m in zip(meshes, results):
        assert m is not None and len(m.faces) == len(f) and m.format == "psq"
    print("ok")
""")


def test_gil_is_released_while_reading(tmp_path):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(__file__), env.get("PYTHONPATH", "")])
    r = subprocess.run([sys.executable, "-c", GIL_SCRIPT, str(tmp_path)], env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "ok"
