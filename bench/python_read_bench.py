#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""psq's Python face, measured (bench/RESULTS.md, "Python").

1. psq.read of a generated .psq (psq-meshgen --triangles N, psq convert:
   16 bits, the fast profile that psq convert picks at this size), M
   triangles/s, beside C++ decode_mesh (psq_bench_compare's
   psq-fast-q16-arrays) and Draco (draco-q16-cl7, libdraco's decoder, as
   DracoPy would call it) on the same mesh, each ratio taken within one
   round so that the shared machine's drift between rounds cancels.
2. Two threads each decoding the mesh (psq.decode of the same bytes) beside
   one thread decoding it twice: the GIL is released.
3. psq.batch.convert of F small generated PLY files to .psq on a
   LocalCluster of 1 and of 2 workers (the cluster started before the clock).

    PYTHONPATH=build/python /usr/bin/python3 bench/python_read_bench.py --build build
        [--triangles 10M] [--rounds 5] [--runs 5] [--files 50] [--file-triangles 100k] [--pin CPU]

Needs a build with -DPSQ_BUILD_BENCH=ON and the Python module (./build.sh
build). Prints a Markdown section; the load average is printed with it.
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def best(seconds):
    return min(seconds)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default="build")
    ap.add_argument("--triangles", default="10M")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--runs", type=int, default=5, help="timed runs per round (the best counts)")
    ap.add_argument("--files", type=int, default=50)
    ap.add_argument("--file-triangles", default="100k")
    ap.add_argument("--pin", help="run the C++ comparison on this processor (taskset), as bench/speed_ratio.sh")
    ap.add_argument("--tmpdir", default=None)
    a = ap.parse_args()

    import json
    import numpy as np
    import psq
    import psq.batch

    build = os.path.abspath(a.build)
    meshgen, psq_bin = f"{build}/psq-meshgen", f"{build}/psq"
    compare = f"{build}/bench/psq_bench_compare"
    for tool in (meshgen, psq_bin, compare):
        if not os.access(tool, os.X_OK):
            print(f"python_read_bench: {tool} not found (build with -DPSQ_BUILD_BENCH=ON)", file=sys.stderr)
            return 2
    out = []
    with tempfile.TemporaryDirectory(dir=a.tmpdir, prefix="psq-pybench-") as tmp:
        ply, path = f"{tmp}/x.ply", f"{tmp}/x.psq"
        run([meshgen, "--triangles", a.triangles, "-q", "-o", ply])
        run([psq_bin, "convert", ply, path, "-q"])
        data = open(path, "rb").read()
        mesh = psq.read(path)
        triangles = len(mesh.faces)
        del mesh
        load0 = os.getloadavg()

        # 1. psq.read against C++ decode_mesh and Draco, round by round.
        rows = []
        for r in range(a.rounds):
            py_read, py_decode = [], []
            for _ in range(a.runs):
                t = time.perf_counter()
                m = psq.read(path)
                py_read.append(time.perf_counter() - t)
                del m
                t = time.perf_counter()
                m = psq.decode(data)
                py_decode.append(time.perf_counter() - t)
                del m
            js = f"{tmp}/c{r}.json"
            cmd = [compare, "--best", "--runs", str(a.runs), "-q", "--codecs", "psq-fast-q16-arrays,draco-q16-cl7",
                   "--json", js, ply]
            if a.pin:
                cmd = ["taskset", "-c", a.pin] + cmd
            run(cmd)
            codecs = {c["codec"]: c for c in json.load(open(js))["meshes"][0]["codecs"]}
            cpp = best(codecs["psq-fast-q16-arrays"]["decode_seconds"])
            draco = best(codecs["draco-q16-cl7"]["decode_seconds"])
            cpp_bytes = codecs["psq-fast-q16-arrays"]["bytes"]
            rows.append((best(py_read), best(py_decode), cpp, draco, cpp_bytes))

        # 2. Two threads.
        def decode_n(n):
            for _ in range(n):
                psq.decode(data)
        seq, par = [], []
        for _ in range(a.runs):
            t = time.perf_counter()
            decode_n(2)
            seq.append(time.perf_counter() - t)
            threads = [threading.Thread(target=decode_n, args=(1,)) for _ in range(2)]
            t = time.perf_counter()
            for th in threads:
                th.start()
            for th in threads:
                th.join()
            par.append(time.perf_counter() - t)

        # 3. psq.batch, 1 and 2 workers.
        src = f"{tmp}/scans"
        os.mkdir(src)
        for i in range(a.files):
            run([meshgen, "--triangles", a.file_triangles, "--seed", str(i + 1), "-q", "-o", f"{src}/s{i:03d}.ply"])
        from distributed import Client, LocalCluster
        batch = {}
        for workers in (1, 2, 1, 2):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=40)
            client = Client(cluster)
            t = time.perf_counter()
            res = psq.batch.convert(src, f"{tmp}/out{workers}", client=client, overwrite=True)
            batch.setdefault(workers, []).append(time.perf_counter() - t)
            client.close()
            cluster.close()
            assert all(r["ok"] for r in res)
        batch_tri = sum(r["triangles_in"] for r in res)
        load1 = os.getloadavg()

    mt = lambda s: triangles / s / 1e6  # noqa: E731
    out.append(f"Mesh: psq-meshgen --triangles {a.triangles} ({triangles} triangles), psq convert (16 bits, "
               f"fast profile): {len(data)} bytes (psq_bench_compare's psq-fast-q16: {rows[0][4]} bytes).")
    out.append(f"Load average before / after: {load0[0]:.2f} / {load1[0]:.2f} (2 cores, shared).")
    out.append("")
    out.append("| round | psq.read (file) | psq.decode (bytes) | C++ decode_mesh | Draco decode | "
               "read / decode_mesh | read / Draco |")
    out.append("|---:|---:|---:|---:|---:|---:|---:|")
    for i, (rd, dc, cpp, dr, _) in enumerate(rows, 1):
        out.append(f"| {i} | {mt(rd):.2f} | {mt(dc):.2f} | {mt(cpp):.2f} | {mt(dr):.2f} | {cpp / rd:.3f} | "
                   f"{dr / rd:.2f} |")
    med = lambda k: statistics.median(r[k] for r in rows)  # noqa: E731
    out.append(f"| median | {mt(med(0)):.2f} | {mt(med(1)):.2f} | {mt(med(2)):.2f} | {mt(med(3)):.2f} | "
               f"{statistics.median(r[2] / r[0] for r in rows):.3f} | "
               f"{statistics.median(r[3] / r[0] for r in rows):.2f} |")
    out.append("")
    out.append("M triangles/s, best of each round's runs; ratios are speed ratios (above 1: psq.read is faster).")
    out.append("")
    out.append(f"Two decodes of the mesh (psq.decode), best of {a.runs}: one thread after the other "
               f"{best(seq):.3f} s, two threads at once {best(par):.3f} s (ratio {best(seq) / best(par):.2f}).")
    out.append("")
    out.append(f"psq.batch.convert of {a.files} PLY files (psq-meshgen --triangles {a.file_triangles}, seeds 1.."
               f"{a.files}; {batch_tri} triangles in all) to .psq, LocalCluster started before the clock, "
               f"two runs each:")
    out.append("")
    out.append("| workers | seconds | M triangles/s |")
    out.append("|---:|---:|---:|")
    for w in (1, 2):
        for s in batch[w]:
            out.append(f"| {w} | {s:.2f} | {batch_tri / s / 1e6:.2f} |")
    out.append("")
    out.append(f"Speed-up of 2 workers over 1 (best runs): {min(batch[1]) / min(batch[2]):.2f}.")
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
