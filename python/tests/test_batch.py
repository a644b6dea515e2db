# SPDX-License-Identifier: Apache-2.0
"""psq.batch on a local Dask cluster of 2 workers: one malformed file is reported, the others converted."""

import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import psq
from conftest import canonical, grid_mesh

pytest.importorskip("distributed")
import psq.batch  # noqa: E402


@pytest.fixture
def scans(tmp_path):
    d = tmp_path / "scans"
    d.mkdir()
    meshes = {}
    for i in range(5):
        p, f = grid_mesh(10 + 3 * i, 8 + i)
        psq.write(d / f"scan{i}.ply", p, f)
        meshes[f"scan{i}"] = (p, f)
    ply = (d / "scan0.ply").read_bytes()
    (d / "broken.ply").write_bytes(ply[: len(ply) // 2])  # truncated in its vertex data
    return d, meshes


def check_rows(rows, d, out, meshes):
    assert len(rows) == 6
    by_name = {os.path.basename(r["input"]): r for r in rows}
    bad = by_name.pop("broken.ply")
    assert bad["ok"] is False and bad["error_code"] == "truncated" and "byte" in bad["error"]
    assert not (out / "broken.psq").exists()
    for name, r in by_name.items():
        assert r["ok"] is True and r["error"] is None
        stem = name[:-4]
        assert r["output"] == str(out / f"{stem}.psq")
        assert r["bytes_out"] == os.path.getsize(r["output"]) > 0
        assert r["bytes_in"] == os.path.getsize(d / name)
        assert r["seconds"] >= 0
        m = psq.read(r["output"])
        p, f = meshes[stem]
        assert len(m.faces) == len(f) == r["triangles_in"]


def test_batch_convert_on_a_local_cluster(scans, tmp_path):
    d, meshes = scans
    out = tmp_path / "out"
    report = tmp_path / "report.json"
    rows = psq.batch.convert(str(d / "*.ply"), out, workers=2, report=report, lossless=True)
    check_rows(rows, d, out, meshes)
    assert len({r["worker"] for r in rows}) >= 1
    saved = json.loads(report.read_text())
    assert saved["files"] == rows
    assert saved["summary"]["ok"] == 5 and saved["summary"]["failed"] == 1
    # The same outputs again, on a running scheduler given by its address:
    # refused per file without overwrite, converted with it.
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None, silence_logs=40) as cluster:
        again = psq.batch.convert(d, out, scheduler=cluster.scheduler_address)
        assert all(not r["ok"] for r in again)
        assert {r["error_code"] for r in again} == {"usage", "truncated"}
        again = psq.batch.convert(d, out, scheduler=cluster.scheduler_address, overwrite=True, lossless=True)
        check_rows(again, d, out, meshes)


def test_batch_command_line(scans, tmp_path):
    d, meshes = scans
    out = tmp_path / "cli"
    report = tmp_path / "report.csv"
    env = dict(os.environ)
    r = subprocess.run([sys.executable, "-m", "psq.batch", "convert", str(d / "*.ply"), str(out), "--workers", "2",
                        "--report", str(report), "--json"], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 1, r.stderr  # one file failed
    assert "1 of 6 file(s) failed" in r.stderr
    rows = json.loads(r.stdout)
    check_rows(rows, d, out, meshes)
    with open(report, newline="") as f:
        table = list(csv.DictReader(f))
    assert [t["input"] for t in table] == [r["input"] for r in rows]
    assert sum(t["ok"] == "True" for t in table) == 5
    # simplify of the good files only: exit status 0.
    good = [str(d / f"scan{i}.ply") for i in range(5)]
    r = subprocess.run([sys.executable, "-m", "psq.batch", "simplify", *good, str(tmp_path / "small"), "--grid", "4",
                        "--workers", "2", "--to", "ply"], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    assert len(list((tmp_path / "small").glob("*.ply"))) == 5
    r = subprocess.run([sys.executable, "-m", "psq.batch", "simplify", str(d), str(tmp_path / "x"), "--method", "qem"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 2
