#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Independent segments (spec/psq-format.md 4.6): what they cost in bytes
and what they give on every core, measured as a person runs psq.

For one mesh (a PLY given, else a foam ball of --triangles from
psq-meshgen, default 10M):

  size:   psq convert --segment 0 X.ply A.psq    (one segment)
          psq convert X.ply B.psq                (the default segments)
          in both back-ends (--profile fast, compact): bytes and the
          segments' share;
  speed:  on the default rANS file, whole processes with --threads 1 and
          --threads T (default 2), alternating within each of --rounds
          rounds (which goes first alternates), medians and ratios:
            psq verify B.psq
            psq convert B.psq Y.ply
          and decode_mesh() in one process (psq_bench_segments), with the
          peak resident set of each process.

  bench/run_segments.py [--build DIR] [--triangles N] [--rounds N]
      [--threads T] [--work DIR] [--write-results] [MESH.ply]

--write-results rewrites the region of bench/RESULTS.md between
<!-- segments:begin --> and <!-- segments:end --> (placed after the
section "Whole process: psq convert beside Draco's tools" the first time).
Uses Debian's python3 alone.
"""

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile

from run_convert_compare import Failure, replace_region, run

MARKERS = ("<!-- segments:begin -->", "<!-- segments:end -->")
AFTER = "<!-- convert:end -->"


def output_of(argv):
    """The standard output of argv, which must succeed."""
    p = subprocess.run(argv, capture_output=True, text=True)
    if p.returncode != 0:
        raise Failure(f"{' '.join(argv)}: exit {p.returncode}: {p.stderr.strip()}")
    return p.stdout


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh", nargs="?", metavar="MESH.ply")
    ap.add_argument("--build", default=os.path.join(root, "build-bench"))
    ap.add_argument("--triangles", default="10M")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work")
    ap.add_argument("--write-results", action="store_true")
    ap.add_argument("--results", default=os.path.join(here, "RESULTS.md"))
    args = ap.parse_args()
    psq = os.path.join(args.build, "psq")
    meshgen = os.path.join(args.build, "psq-meshgen")
    bench = os.path.join(args.build, "bench", "psq_bench_segments")
    work = args.work or tempfile.mkdtemp(prefix="psq-segments-")
    os.makedirs(work, exist_ok=True)
    try:
        mesh = args.mesh
        if not mesh:
            mesh = os.path.join(work, f"foam{args.triangles}.ply")
            run([meshgen, "--triangles", args.triangles, "-o", mesh])
        name = os.path.basename(mesh)
        sizes = []
        for profile in ("fast", "compact"):
            one = os.path.join(work, f"one-{profile}.psq")
            seg = os.path.join(work, f"seg-{profile}.psq")
            run([psq, "convert", "-q", "-f", "--profile", profile, "--segment", "0", mesh, one])
            run([psq, "convert", "-q", "-f", "--profile", profile, mesh, seg])
            j = json.loads(output_of([psq, "info", "--json", seg]))["psq"]
            sizes.append((profile, os.path.getsize(one), os.path.getsize(seg), j["segments"], j["segment_bytes"]))
        target = os.path.join(work, "seg-fast.psq")
        out_ply = os.path.join(work, "out.ply")
        # (label, argv for a thread count, whether OUT is removed before each
        # run): replacing an existing PLY frees its blocks as the new one is
        # renamed over it, a serial step that is no decoding; both cases are
        # measured (RESULTS, "Independent segments").
        jobs = [
            ("psq verify", lambda t: [psq, "verify", "-q", "--threads", str(t), target], False),
            ("psq convert .psq → PLY (new file)",
             lambda t: [psq, "convert", "-q", "-f", "--threads", str(t), target, out_ply], True),
            ("psq convert .psq → PLY (over an existing file)",
             lambda t: [psq, "convert", "-q", "-f", "--threads", str(t), target, out_ply], False),
        ]
        rows = []
        for label, argv, fresh in jobs:
            times = {1: [], args.threads: []}
            rss = {1: [], args.threads: []}
            for r in range(args.rounds):
                order = (1, args.threads) if r % 2 == 0 else (args.threads, 1)
                for t in order:
                    if fresh and os.path.exists(out_ply):
                        os.remove(out_ply)
                        os.sync()
                    elif not fresh and not os.path.exists(out_ply):
                        run(argv(t))
                    wall, _, peak = run(argv(t))
                    times[t].append(wall)
                    rss[t].append(peak)
            a, b = statistics.median(times[1]), statistics.median(times[args.threads])
            rows.append((label, a, b, a / b, max(rss[1]) / 1024, max(rss[args.threads]) / 1024))
        d = json.loads(output_of([bench, "--rounds", str(args.rounds), "--threads", str(args.threads), target]))
        rows.append(("decode_mesh() in one process", d["seconds_1"], d["seconds_n"], d["speedup"], None, None))
    finally:
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)

    commit = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    lines = [
        "## Independent segments: their cost and every core",
        "",
        f"`bench/run_segments.py --build {os.path.relpath(args.build, root)} --rounds {args.rounds}"
        f"{' ' + args.mesh if args.mesh else ''}` ({name if args.mesh else 'foam ball of ' + args.triangles + ' triangles from psq-meshgen'}; "
        f"{platform.machine()}, {os.cpu_count()} cores, commit {commit}). Size: the default segments "
        "(a quarter of the input's triangles, at least 2^21) against one segment (`--segment 0`). "
        f"Speed: whole processes on the default rANS file, `--threads 1` against `--threads {args.threads}`, "
        f"alternating, median of {args.rounds} rounds; peak resident set of the process. PLY output to a "
        "new file (the previous one removed, untimed) and over an existing one (whose blocks the "
        "replacement frees, a serial step).",
        "",
        "| back-end | one segment | default segments | segments | their bytes | cost |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for profile, one, seg, n, sb in sizes:
        lines.append(f"| {'rANS' if profile == 'fast' else 'adaptive'} | {one:,} | {seg:,} | {n} | {sb:,} | "
                     f"{100.0 * (seg - one) / one:+.2f}% |")
    lines += ["", f"| what | 1 thread (s) | {args.threads} threads (s) | speedup | RSS 1 (MiB) | RSS {args.threads} (MiB) |",
              "|---|---:|---:|---:|---:|---:|"]
    for label, a, b, ratio, r1, rn in rows:
        rs = f"{r1:.1f} | {rn:.1f}" if r1 is not None else "– | –"
        lines.append(f"| {label} | {a:.3f} | {b:.3f} | {ratio:.2f}x | {rs} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write_results:
        with open(args.results) as f:
            res = f.read()
        res = replace_region(res, MARKERS, text, AFTER)
        with open(args.results, "w") as f:
            f.write(res)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Failure as e:
        print(f"run_segments.py: {e}", file=sys.stderr)
        sys.exit(1)
