# SPDX-License-Identifier: Apache-2.0
"""psq.convert, psq.simplify, psq.info and psq.distance (compared with the psq command where it is built)."""

import json
import subprocess

import numpy as np
import pytest

import psq
from conftest import canonical, grid_mesh


@pytest.fixture
def ply(tmp_path):
    p, f = grid_mesh(40, 30)
    path = tmp_path / "m.ply"
    psq.write(path, p, f, vertex_properties={"q": np.arange(len(p), dtype=np.float32)})
    return path


def test_convert_to_every_format_and_back(tmp_path, ply):
    src = psq.read(ply)
    for ext, opts in (("psq", {"lossless": True}), ("ply", {"ascii": True}), ("obj", {}), ("drc", {"lossless": True})):
        out = tmp_path / f"c.{ext}"
        r = psq.convert(ply, out, **opts)
        assert r["output_format"] == ext and r["triangles"] == len(src.faces)
        assert r["bytes_out"] == out.stat().st_size
        m = psq.read(out)
        assert canonical(m.positions, m.faces) == canonical(src.positions, src.faces)
    with pytest.raises(psq.UsageError):
        psq.convert(ply, tmp_path / "c.psq", overwrite=False)
    with pytest.raises(psq.UsageError):
        psq.convert(ply, ply)


def test_convert_summary_matches_the_command(tmp_path, ply, psq_binary):
    if psq_binary is None:
        pytest.skip("the psq tool is not built")
    ours = psq.convert(ply, tmp_path / "a.psq", measure_costs=True, threads=2)
    cli = json.loads(subprocess.run([psq_binary, "convert", str(ply), str(tmp_path / "b.psq"), "--json", "-q"],
                                    capture_output=True, text=True, check=True).stdout)
    for key, value in cli.items():
        if key not in ("input", "output"):
            assert ours[key] == value, key
    assert (tmp_path / "a.psq").read_bytes() == (tmp_path / "b.psq").read_bytes()


@pytest.mark.parametrize("source", ["ply", "psq"])
def test_info_has_the_fields_of_psq_info_json(tmp_path, ply, psq_binary, source):
    path = ply
    if source == "psq":
        path = tmp_path / "m.psq"
        psq.convert(ply, path)
    ours = psq.info(path)
    assert ours["vertices"] == 1200 and ours["triangles"] == 2 * 39 * 29
    assert ours["components"] == 1 and ours["border_loops"] == 1 and ours["handles"] == 0
    assert ours["vertex_properties"] == [{"name": "q", "type": "float"}]
    if psq_binary is None:
        pytest.skip("the psq tool is not built")
    cli = json.loads(subprocess.run([psq_binary, "info", str(path), "--json", "-q"], capture_output=True, text=True,
                                    check=True).stdout)
    assert ours == cli


def test_distance_has_the_fields_of_psq_distance_json(tmp_path, ply, psq_binary):
    out = tmp_path / "q.psq"
    psq.convert(ply, out, bits=8)
    ours = psq.distance(ply, out, samples=5000, seed=3)
    assert ours["a_to_b"]["samples"] == 5000 and 0 < ours["hausdorff"] < 0.2
    same = psq.distance(ply, ply, samples=1000)
    assert same["hausdorff"] == 0
    if psq_binary is None:
        pytest.skip("the psq tool is not built")
    cli = json.loads(subprocess.run([psq_binary, "distance", str(ply), str(out), "--samples", "5000", "--seed", "3",
                                     "--json"], capture_output=True, text=True, check=True).stdout)
    ours.pop("timing")
    cli.pop("timing")
    assert ours == cli


@pytest.mark.parametrize("method,opts", [("clustering", {"grid": 10}), ("clustering", {"ratio": 0.25}),
                                         ("qem", {"ratio": 0.25}), ("qem", {"triangles": 500})])
def test_simplify(tmp_path, ply, method, opts):
    for src in (ply, tmp_path / "m.psq"):
        if src.suffix == ".psq":
            psq.convert(ply, src)
        out = tmp_path / f"s_{src.suffix[1:]}.ply"
        r = psq.simplify(src, out, method=method, **opts)
        m = psq.read(out)
        assert r["output_triangles"] == len(m.faces) > 0
        assert r["input_triangles"] == 2 * 39 * 29
        assert len(m.faces) < 0.5 * r["input_triangles"]
        if "ratio" in opts:
            assert abs(len(m.faces) - 0.25 * r["input_triangles"]) < 0.1 * r["input_triangles"]
        d = psq.distance(ply, out, samples=2000)
        assert d["relative"]["hausdorff"] < 0.1


def test_simplify_checks_its_options(tmp_path, ply):
    with pytest.raises(psq.UsageError):
        psq.simplify(ply, tmp_path / "o.psq", method="qem")  # no target
    with pytest.raises(psq.UsageError):
        psq.simplify(ply, tmp_path / "o.psq", method="magic", ratio=0.5)
    with pytest.raises(psq.UsageError):
        psq.simplify(ply, tmp_path / "o.psq", ratio=1.5)
    with pytest.raises(psq.UnknownFormatError):
        (tmp_path / "junk.ply").write_bytes(b"junk" * 30)
        psq.simplify(tmp_path / "junk.ply", tmp_path / "o.psq", grid=8)
    assert not (tmp_path / "o.psq").exists()


def test_example_script_loads_a_psq(tmp_path):
    import os
    import sys
    p, f = grid_mesh(8)
    psq.write(tmp_path / "m.psq", p, f)
    script = os.path.join(os.path.dirname(__file__), "..", "examples", "load_psq.py")
    r = subprocess.run([sys.executable, script, str(tmp_path / "m.psq")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "psq.Mesh(64 vertices" in r.stdout
    r = subprocess.run([sys.executable, script, str(tmp_path / "m.psq"), "--stream"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and "98 triangles" in r.stdout, r.stderr


def test_simplify_of_a_lossless_psq(tmp_path, ply):
    src = tmp_path / "l.psq"
    psq.convert(ply, src, lossless=True)
    r = psq.simplify(src, tmp_path / "c.psq", grid=12)  # clustering measures the box first
    assert r["passes"] == 2 and r["lossless"] is False and r["bits"] == 16
    r = psq.simplify(src, tmp_path / "q.psq", method="qem", ratio=0.5)
    assert r["lossless"] is True  # no box before the first vertex: stays lossless
    with pytest.raises(psq.UsageError):
        psq.simplify(src, tmp_path / "q2.psq", method="qem", ratio=0.5, bits=12)
    for out in ("c.psq", "q.psq"):
        assert len(psq.read(tmp_path / out).faces) > 0


def test_convert_welds_a_soup_and_quantizes_normals(tmp_path, psq_binary):
    # A soup of a closed grid (each triangle its own three vertices), with a
    # normal per vertex: weld merges the copies (same position and normal),
    # as psq convert --weld does, and normals are quantized at normal_bits.
    grid, grid_faces = grid_mesh(12)
    corners = grid_faces.reshape(-1)
    positions = grid[corners]
    lifted = positions.astype(np.float64) + [0, 0, 5]
    normals = (lifted / np.linalg.norm(lifted, axis=1, keepdims=True)).astype(np.float32)
    faces = np.arange(len(corners), dtype=np.uint32).reshape(-1, 3)
    soup = tmp_path / "soup.ply"
    psq.write(soup, positions, faces, lossless=True,
              vertex_properties={"nx": normals[:, 0].copy(), "ny": normals[:, 1].copy(), "nz": normals[:, 2].copy()})
    ours = psq.convert(soup, tmp_path / "w.psq", weld="all", normal_bits=8, measure_costs=True)
    assert ours["weld"] == "all" and ours["input_vertices"] == len(corners)
    assert ours["vertices"] == len(grid) and ours["welded_vertices"] == len(corners) - len(grid)
    back = psq.read(tmp_path / "w.psq")
    n = np.stack([back.vertex_properties[k] for k in ("nx", "ny", "nz")], axis=1)
    assert np.all(np.abs(np.linalg.norm(n, axis=1) - 1) < 0.02)
    if psq_binary is not None:
        cli = json.loads(subprocess.run([psq_binary, "convert", str(soup), str(tmp_path / "c.psq"), "--json", "-q",
                                         "--weld", "--normal-bits", "8", "--threads", "1"],
                                        capture_output=True, text=True, check=True).stdout)
        for key, value in cli.items():
            if key not in ("input", "output"):
                assert ours[key] == value, key
        assert (tmp_path / "w.psq").read_bytes() == (tmp_path / "c.psq").read_bytes()
    with pytest.raises(psq.UsageError):
        psq.convert(soup, tmp_path / "w.ply", weld="all")


def test_convert_welds_corners(tmp_path, psq_binary):
    # A grid split along a texture seam (column 6's vertices copied, the
    # copies' u 0.5 larger): weld="corners" merges the copies, the texture
    # coordinates kept per corner, as psq convert --weld=corners does.
    grid, faces = grid_mesh(12)
    uv = (grid[:, :2] / 12.0).astype(np.float32)
    seam = np.flatnonzero(grid[:, 0] == 6)
    copies = np.arange(len(grid), len(grid) + len(seam), dtype=np.uint32)
    remap = np.arange(len(grid), dtype=np.uint32)
    remap[seam] = copies
    right = grid[faces].mean(axis=1)[:, 0] > 6
    faces = faces.copy()
    faces[right] = remap[faces[right]]
    positions = np.concatenate([grid, grid[seam]])
    uv = np.concatenate([uv, uv[seam] + [0.5, 0]]).astype(np.float32)
    split = tmp_path / "split.ply"
    psq.write(split, positions, faces, lossless=True,
              vertex_properties={"u": uv[:, 0].copy(), "v": uv[:, 1].copy()})
    ours = psq.convert(split, tmp_path / "w.psq", weld="corners", uv_bits=12)
    assert ours["weld"] == "corners" and ours["welded_vertices"] == len(seam)
    assert ours["vertices"] == len(grid)
    back = psq.read(tmp_path / "w.psq")
    assert "corner_uv" in back.face_properties and "u" not in back.vertex_properties
    if psq_binary is not None:
        cli = json.loads(subprocess.run([psq_binary, "convert", str(split), str(tmp_path / "c.psq"), "--json", "-q",
                                         "--weld=corners", "--uv-bits", "12", "--threads", "1"],
                                        capture_output=True, text=True, check=True).stdout)
        assert cli["welded_vertices"] == ours["welded_vertices"]
        assert (tmp_path / "w.psq").read_bytes() == (tmp_path / "c.psq").read_bytes()
