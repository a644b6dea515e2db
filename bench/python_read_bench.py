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
   one thread decoding it twice: the GIL is released. The same with two
   processes beside one (each started, then released at a common instant)
   is the control: what the machine gives two decoders at that moment.
3. psq.batch.convert of F small generated PLY files to .psq on a
   LocalCluster of 1 and of 2 workers (the cluster started before the clock).

    PYTHONPATH=build/python /usr/bin/python3 bench/python_read_bench.py --build build
        [--triangles 10M] [--rounds 5] [--runs 5] [--files 50] [--file-triangles 100k] [--pin CPU]
        [--parts read,threads,batch]

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


# A child of the process control: imports psq and loads the bytes, waits
# for the common start instant, decodes n times, prints its elapsed time.
CHILD = """
import sys, time
import psq
data = open(sys.argv[1], "rb").read()
start, n = float(sys.argv[2]), int(sys.argv[3])
while time.time() < start:
    time.sleep(0.0005)
for _ in range(n):
    psq.decode(data)
print(time.time() - start)
"""


def processes(path, counts):
    """Elapsed seconds until the last of len(counts) processes, each decoding counts[i] times, is done."""
    start = time.time() + 2.0
    children = [subprocess.Popen([sys.executable, "-c", CHILD, path, repr(start), str(n)], stdout=subprocess.PIPE,
                                 text=True, env=dict(os.environ)) for n in counts]
    return max(float(c.communicate()[0]) for c in children)


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
    ap.add_argument("--parts", default="read,threads,batch", help="which measurements (default: all three)")
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

        parts = set(a.parts.split(","))
        # 1. psq.read against C++ decode_mesh and Draco, round by round.
        rows = []
        for r in range(a.rounds if "read" in parts else 0):
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
        seq, par, pseq, ppar = [], [], [], []
        for _ in range(a.runs if "threads" in parts else 0):
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
            pseq.append(processes(path, [2]))
            ppar.append(processes(path, [1, 1]))

        # 3. psq.batch, 1 and 2 workers.
        src = f"{tmp}/scans"
        os.mkdir(src)
        batch = {}
        batch_tri = 0
        for i in range(a.files if "batch" in parts else 0):
            run([meshgen, "--triangles", a.file_triangles, "--seed", str(i + 1), "-q", "-o", f"{src}/s{i:03d}.ply"])
        from distributed import Client, LocalCluster
        for workers in ((1, 2, 1, 2) if "batch" in parts else ()):
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
               f"fast profile): {len(data)} bytes.")
    out.append(f"Load average before / after: {load0[0]:.2f} / {load1[0]:.2f} (2 cores, shared).")
    out.append("")
    if rows:
        out.append(f"psq_bench_compare's psq-fast-q16 stream of the same PLY: {rows[0][4]} bytes.")
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
    if seq:
        out.append(f"Two decodes of the mesh (psq.decode), best of {a.runs}, seconds:")
        out.append("")
        out.append("| | one after the other | two at once | ratio |")
        out.append("|---|---:|---:|---:|")
        out.append(f"| threads of one process | {best(seq):.3f} | {best(par):.3f} | {best(seq) / best(par):.2f} |")
        out.append(f"| processes (the control) | {best(pseq):.3f} | {best(ppar):.3f} | "
                   f"{best(pseq) / best(ppar):.2f} |")
        out.append("")
    if batch:
        out.append(f"psq.batch.convert of {a.files} PLY files (psq-meshgen --triangles {a.file_triangles}, seeds 1.."
                   f"{a.files}; {batch_tri} triangles in all) to .psq, LocalCluster started before the clock, "
                   f"two runs each:")
        out.append("")
        out.append("| workers | seconds | M triangles/s |")
        out.append("|---:|---:|---:|")
        for w in (1, 2):
            for sec in batch[w]:
                out.append(f"| {w} | {sec:.2f} | {batch_tri / sec / 1e6:.2f} |")
        out.append("")
        out.append(f"Speed-up of 2 workers over 1 (best runs): {min(batch[1]) / min(batch[2]):.2f}.")
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
