# SPDX-License-Identifier: Apache-2.0
"""Round trips through numpy: every format psq writes or reads, every property kind."""

import struct

import numpy as np
import pytest

import psq
from conftest import canonical, grid_mesh

SCALARS = [np.int8, np.uint8, np.int16, np.uint16, np.int32, np.uint32, np.float32, np.float64]


def scalar_props(count, seed):
    rng = np.random.default_rng(seed)
    out = {}
    for t in SCALARS:
        name = "p_" + np.dtype(t).name
        if np.dtype(t).kind == "f":
            out[name] = rng.standard_normal(count).astype(t)
        else:
            info = np.iinfo(t)
            out[name] = rng.integers(info.min, info.max, size=count, endpoint=True, dtype=t)
    return out


def list_prop(count, dtype, count_type, seed):
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 4, size=count).astype(np.uint32)
    values = (rng.standard_normal(int(counts.sum())) * 100).astype(dtype)
    return psq.ListProperty(counts, values, count_type)


def by_vertex(mesh):
    """Order of the mesh's vertices by position (they are distinct in the grid)."""
    return np.lexsort(mesh.positions.T[::-1])


@pytest.mark.parametrize("ext", ["psq", "ply"])
@pytest.mark.parametrize("position_dtype", [np.float32, np.float64])
def test_properties_of_every_kind_round_trip(tmp_path, ext, position_dtype):
    p, f = grid_mesh(9, 7, dtype=position_dtype)
    vp = scalar_props(len(p), 1)
    vp["vl"] = list_prop(len(p), np.int16, "uint8", 2)
    fp = scalar_props(len(f), 3)
    fp["fl"] = list_prop(len(f), np.float32, "uint16", 4)
    path = tmp_path / f"m.{ext}"
    psq.write(path, p, f, lossless=True, vertex_properties=vp, face_properties=fp)
    m = psq.read(path)
    assert m.format == ext
    assert m.positions.dtype == position_dtype
    assert m.faces.dtype == np.uint32 and m.faces.shape == f.shape
    # The .psq may renumber vertices: compare per vertex, matched by position.
    src, dst = by_vertex(psq.Mesh(p, f)), by_vertex(m)
    np.testing.assert_array_equal(m.positions[dst], p[src])
    for name, v in vp.items():
        got = m.vertex_properties[name]
        if isinstance(v, psq.ListProperty):
            assert isinstance(got, psq.ListProperty) and got.values.dtype == v.values.dtype
            for a, b in zip(src, dst):
                np.testing.assert_array_equal(got[int(b)], v[int(a)])
        else:
            assert got.dtype == v.dtype, name
            np.testing.assert_array_equal(got[dst], v[src])
    # Faces: compare each face's property by its corners' positions.
    key_src = {tuple(sorted(map(tuple, p[t]))): i for i, t in enumerate(f.astype(np.int64))}
    perm = np.array([key_src[tuple(sorted(map(tuple, m.positions[t])))] for t in m.faces.astype(np.int64)])
    for name, v in fp.items():
        got = m.face_properties[name]
        if isinstance(v, psq.ListProperty):
            assert got.count_type == v.count_type
            for i, j in enumerate(perm):
                np.testing.assert_array_equal(got[i], v[int(j)])
        else:
            assert got.dtype == v.dtype, name
            np.testing.assert_array_equal(got, v[perm])
    assert canonical(m.positions, m.faces) == canonical(p, f)


@pytest.mark.parametrize("ext,kwargs", [("psq", {"lossless": True}), ("ply", {}), ("ply", {"ascii": True}),
                                        ("obj", {}), ("drc", {"lossless": True})])
def test_geometry_round_trips_through_every_written_format(tmp_path, ext, kwargs):
    p, f = grid_mesh(12)
    path = tmp_path / f"m.{ext}"
    psq.write(path, p, f, **kwargs)
    m = psq.read(path)
    assert m.format == ext
    assert len(m.faces) == len(f)
    assert canonical(m.positions.astype(np.float32), m.faces) == canonical(p, f)


def test_quantized_psq_is_within_half_a_step(tmp_path):
    p, f = grid_mesh(30)
    data = psq.encode(p, f, bits=12)
    m = psq.decode(data)
    extent = float((p.max(0) - p.min(0)).max())
    step = extent / ((1 << 12) - 1)
    src, dst = by_vertex(psq.Mesh(p, f)), by_vertex(m)
    assert np.abs(m.positions[dst].astype(np.float64) - p[src]).max() <= 0.5 * step * 1.0001
    assert len(m.faces) == len(f)


def test_encode_decode_bytes_and_read_of_bytes_agree(tmp_path):
    p, f = grid_mesh(15)
    data = psq.encode(p, f, lossless=True)
    assert isinstance(data, bytes) and data[:8] == b"\x89PSQ\r\n\x1a\n"
    a = psq.decode(data)
    b = psq.read(data)
    (tmp_path / "m.psq").write_bytes(data)
    c = psq.read(tmp_path / "m.psq")
    for m in (a, b, c):
        assert canonical(m.positions, m.faces) == canonical(p, f)
    np.testing.assert_array_equal(a.faces, c.faces)


def test_off_and_stl_are_read(tmp_path):
    p, f = grid_mesh(5)
    off = "OFF\n%d %d 0\n" % (len(p), len(f))
    off += "".join("%r %r %r\n" % tuple(map(float, v)) for v in p)
    off += "".join("3 %d %d %d\n" % tuple(t) for t in f)
    (tmp_path / "m.off").write_text(off)
    m = psq.read(tmp_path / "m.off")
    assert m.format == "off"
    assert canonical(m.positions, m.faces) == canonical(p, f)
    stl = bytearray(80) + struct.pack("<I", len(f))
    for t in f:
        stl += struct.pack("<3f", 0, 0, 0) + p[t].astype("<f4").tobytes() + b"\0\0"
    (tmp_path / "m.stl").write_bytes(bytes(stl))
    m = psq.read(tmp_path / "m.stl")
    assert m.format == "stl"
    assert canonical(m.positions, m.faces) == canonical(p, f)


def test_a_mesh_object_can_be_written_back(tmp_path):
    p, f = grid_mesh(6)
    psq.write(tmp_path / "a.ply", p, f, vertex_properties={"q": np.arange(len(p), dtype=np.uint16)})
    m = psq.read(tmp_path / "a.ply")
    psq.write(tmp_path / "b.psq", m)
    n = psq.read(tmp_path / "b.psq")
    assert set(n.vertex_properties) == {"q"}
    assert sorted(n.vertex_properties["q"].tolist()) == list(range(len(p)))


def test_faces_of_other_integer_types_and_python_lists_are_accepted(tmp_path):
    p, f = grid_mesh(4)
    data = psq.encode(p.tolist(), f.astype(np.int64), lossless=True)
    m = psq.decode(data)
    assert m.positions.dtype == np.float64  # a list of floats is float64
    assert len(m.faces) == len(f)


def test_what_a_format_cannot_hold_is_dropped_with_a_warning(tmp_path):
    p, f = grid_mesh(5)
    fp = {"material": np.arange(len(f), dtype=np.uint8)}
    with pytest.warns(psq.FormatWarning, match="material"):
        psq.write(tmp_path / "m.obj", p, f, face_properties=fp)
    f2 = f.copy()
    f2[0] = [1, 1, 2]
    with pytest.warns(psq.FormatWarning, match="1 degenerate"):
        psq.write(tmp_path / "m.psq", p, f2)
    assert len(psq.read(tmp_path / "m.psq").faces) == len(f) - 1
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        psq.write(tmp_path / "m.ply", p, f, face_properties=fp)  # PLY holds it: no warning
