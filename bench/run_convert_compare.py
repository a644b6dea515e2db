#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The whole-process benchmark: psq convert beside Draco's command-line tools.

What a person runs is a process from file to file, so this times processes:

  encode:  psq convert -q -f --bits B X.ply X.psq
           draco_encoder -i X.ply -o X.drc -cl 7 -qp B
  decode:  psq convert -q -f X.psq Y.ply
           draco_decoder -i X.drc -o Y.ply

for every mesh, N rounds (--rounds, default 3), the two tools alternating
within a round (which goes first alternates from round to round), and
reports medians: wall seconds, million triangles a second, the ratio of
speeds (psq / Draco: above 1, psq is faster), the peak resident set of each
process (from wait4's rusage), and the file sizes. Both tools write binary
little-endian PLY. psq convert picks its profile itself (--profile auto:
fast from 131,072 triangles); Draco runs with its defaults otherwise.

Meshes: the PLY files given, or by default the shared meshes of 200,000
triangles and more (../shared/data/meshes beside the repository, when
present) and foam balls from psq-meshgen at --sizes (default "1M 10M"),
each in coherent order and shuffled (vertices and triangles permuted:
psq-meshgen --order shuffled). Generated meshes go to --work (default a
temporary directory, removed at the end), and so do the outputs.

  bench/run_convert_compare.py [--build DIR] [--sizes "1M 10M"] [--no-shared]
      [--rounds N] [--bits B] [--work DIR] [--json FILE] [--write-results]
      [--results FILE] [--readme FILE] [MESH.ply]...
  bench/run_convert_compare.py --build build-bench --write-results   # what bench/RESULTS.md shows

--write-results rewrites the region of bench/RESULTS.md between
<!-- convert:begin --> and <!-- convert:end --> (inserted after the section
"Speed ratios to Draco within one invocation" the first time) and the
region of README.md between <!-- convert-headline:begin --> and
<!-- convert-headline:end --> (inserted after the headline table that
bench/make_results.py writes); nothing is written if the run fails. psq and
psq-meshgen come from --build (configure with -DPSQ_BUILD_BENCH=ON for
psq-meshgen); draco_encoder and draco_decoder from PATH. Uses Debian's
python3 alone.
"""

import argparse
import datetime
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

MARKERS = ("<!-- convert:begin -->", "<!-- convert:end -->")
README_MARKERS = ("<!-- convert-headline:begin -->", "<!-- convert-headline:end -->")
SECTION_AFTER = "## Speed ratios to Draco within one invocation"
README_AFTER = "<!-- bench-headline:end -->"
MIN_SHARED_TRIANGLES = 200000


class Failure(Exception):
    pass


def ply_counts(path):
    """(vertices, faces) from a PLY header."""
    counts = {}
    with open(path, "rb") as f:
        for _ in range(200):
            line = f.readline()
            if not line:
                break
            words = line.decode("latin-1").split()
            if len(words) == 3 and words[0] == "element":
                counts[words[1]] = int(words[2])
            if words[:1] == ["end_header"]:
                break
    if "vertex" not in counts or "face" not in counts:
        raise Failure(f"{path}: not a PLY with vertex and face elements")
    return counts["vertex"], counts["face"]


def run(argv):
    """Runs argv; returns (wall seconds, processor seconds, peak RSS in KiB).
    Raises on failure."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    # wait4 gives this child's own rusage (RUSAGE_CHILDREN would take the
    # maximum over every child so far).
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise Failure(f"{' '.join(argv)}: exit {proc.returncode}: {err.decode(errors='replace').strip()}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss


def parse_size(text):
    m = re.fullmatch(r"(\d+(?:\.\d+)?)([kKmMgG]?)", text)
    if not m:
        raise Failure(f"bad size '{text}'")
    return int(float(m.group(1)) * {"": 1, "k": 1e3, "m": 1e6, "g": 1e9}[m.group(2).lower()])


def meshes_to_run(args, work):
    meshes = []
    for path in args.meshes:
        meshes.append((os.path.splitext(os.path.basename(path))[0], path, None))
    if args.meshes:
        return meshes
    if not args.no_shared:
        shared = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "meshes")
        if os.path.isdir(shared):
            for name in sorted(os.listdir(shared)):
                path = os.path.join(shared, name)
                if name.endswith(".ply") and ply_counts(path)[1] >= MIN_SHARED_TRIANGLES:
                    meshes.append((name[:-4], path, None))
    meshgen = os.path.join(args.build, "psq-meshgen")
    for size in args.sizes.split():
        for order in ("coherent", "shuffled"):
            name = f"foam_{size}" + ("_shuffled" if order == "shuffled" else "")
            path = os.path.join(work, name + ".ply")
            if not os.path.exists(path):
                if not os.path.exists(meshgen):
                    raise Failure(f"{meshgen} not found (configure --build with -DPSQ_BUILD_BENCH=ON)")
                subprocess.run([meshgen, "--triangles", str(parse_size(size)), "--order", order, "-q", "-o", path],
                               check=True)
            meshes.append((name, path, f"psq-meshgen --triangles {size} --order {order}"))
    return meshes


def measure(args, name, path, work):
    psq = os.path.join(args.build, "psq")
    _, triangles = ply_counts(path)
    out_psq = os.path.join(work, name + ".out.psq")
    out_drc = os.path.join(work, name + ".out.drc")
    back = os.path.join(work, name + ".back.ply")
    bits = str(args.bits)
    tools = {
        "encode": {
            "psq": [psq, "convert", "-q", "-f", "--bits", bits, path, out_psq],
            "draco": ["draco_encoder", "-i", path, "-o", out_drc, "-cl", "7", "-qp", bits],
        },
        "decode": {
            "psq": [psq, "convert", "-q", "-f", out_psq, back],
            "draco": ["draco_decoder", "-i", out_drc, "-o", back],
        },
    }
    samples = {(stage, tool): [] for stage in tools for tool in ("psq", "draco")}
    for r in range(args.rounds):
        order = ("psq", "draco") if r % 2 == 0 else ("draco", "psq")
        for stage in ("encode", "decode"):
            for tool in order:
                samples[(stage, tool)].append(run(tools[stage][tool]))
    row = {"mesh": name, "triangles": triangles, "input_bytes": os.path.getsize(path),
           "psq_bytes": os.path.getsize(out_psq), "draco_bytes": os.path.getsize(out_drc)}
    for (stage, tool), runs in samples.items():
        wall = statistics.median(w for w, _, _ in runs)
        row[f"{stage}_{tool}_seconds"] = wall
        row[f"{stage}_{tool}_seconds_all"] = [round(w, 3) for w, _, _ in runs]
        row[f"{stage}_{tool}_cpu_seconds"] = statistics.median(c for _, c, _ in runs)
        row[f"{stage}_{tool}_mtps"] = triangles / wall / 1e6
        row[f"{stage}_{tool}_rss_mib"] = max(m for _, _, m in runs) / 1024.0
    for stage in ("encode", "decode"):
        # Medians of the per-round ratios: each round's pair ran back to
        # back. Wall time is what a person waits for; processor time (user
        # and system, all threads) is less disturbed by other processes on
        # a shared machine, but does not credit psq's second thread.
        pairs = list(zip(samples[(stage, "psq")], samples[(stage, "draco")]))
        row[f"{stage}_ratio"] = statistics.median(d[0] / p[0] for p, d in pairs)
        row[f"{stage}_cpu_ratio"] = statistics.median(d[1] / p[1] for p, d in pairs)
    for f in (out_psq, out_drc, back):
        if os.path.exists(f) and not args.work:
            os.remove(f)
    return row


def fmt_int(n):
    return f"{n:,}"


def table(rows, meta):
    lines = []
    lines.append(f"## Whole process: psq convert beside Draco's tools ({meta['date']})")
    lines.append("")
    lines.append("File to file, as a person runs them: `psq convert -q -f --bits "
                 f"{meta['bits']} X.ply X.psq` beside `draco_encoder -i X.ply -o X.drc -cl 7 -qp {meta['bits']}`, "
                 "and `psq convert -q -f X.psq Y.ply` beside `draco_decoder -i X.drc -o Y.ply` (both write "
                 "binary PLY; psq picks the fast profile from 131,072 triangles). "
                 f"Medians of {meta['rounds']} rounds, the tools alternating; a ratio is the median of the "
                 "rounds' psq speed / Draco speed (above 1: psq is faster), from wall time; the CPU ratio is the "
                 "same from processor time (user + system, all threads: psq's second thread counts against it), "
                 "which other processes on this shared machine disturb less. RSS: the largest peak resident set "
                 "of the rounds.")
    lines.append("")
    lines.append("| mesh | triangles | encode psq s | Draco s | psq M tri/s | Draco M tri/s | **ratio** | CPU s psq / Draco | CPU ratio | psq RSS MiB | Draco RSS MiB |")
    lines.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        lines.append(f"| {r['mesh']} | {fmt_int(r['triangles'])} | {r['encode_psq_seconds']:.3f} | "
                     f"{r['encode_draco_seconds']:.3f} | {r['encode_psq_mtps']:.2f} | {r['encode_draco_mtps']:.2f} | "
                     f"**{r['encode_ratio']:.2f}** | {r['encode_psq_cpu_seconds']:.3f} / {r['encode_draco_cpu_seconds']:.3f} | "
                     f"{r['encode_cpu_ratio']:.2f} | {r['encode_psq_rss_mib']:.0f} | {r['encode_draco_rss_mib']:.0f} |")
    lines.append("")
    lines.append("| mesh | decode psq s | Draco s | psq M tri/s | Draco M tri/s | **ratio** | CPU s psq / Draco | CPU ratio | psq RSS MiB | Draco RSS MiB | .psq bytes | .drc bytes | .psq / .drc |")
    lines.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        lines.append(f"| {r['mesh']} | {r['decode_psq_seconds']:.3f} | {r['decode_draco_seconds']:.3f} | "
                     f"{r['decode_psq_mtps']:.2f} | {r['decode_draco_mtps']:.2f} | **{r['decode_ratio']:.2f}** | "
                     f"{r['decode_psq_cpu_seconds']:.3f} / {r['decode_draco_cpu_seconds']:.3f} | {r['decode_cpu_ratio']:.2f} | "
                     f"{r['decode_psq_rss_mib']:.0f} | {r['decode_draco_rss_mib']:.0f} | {fmt_int(r['psq_bytes'])} | "
                     f"{fmt_int(r['draco_bytes'])} | {r['psq_bytes'] / r['draco_bytes']:.3f} |")
    lines.append("")
    by_name = {r["mesh"]: r for r in rows}
    pairs = [(n, by_name[n + "_shuffled"]) for n in by_name if n + "_shuffled" in by_name]
    if pairs:
        parts = []
        for n, s in pairs:
            c = by_name[n]
            parts.append(f"{n} {s['encode_psq_seconds'] / c['encode_psq_seconds']:.2f} "
                         f"(Draco {s['encode_draco_seconds'] / c['encode_draco_seconds']:.2f})")
        lines.append("Shuffled over coherent, encode time of psq: " + "; ".join(parts) + ".")
        lines.append("")
    lines.append(f"Median ratio, encode: {statistics.median(r['encode_ratio'] for r in rows):.2f} "
                 f"(CPU {statistics.median(r['encode_cpu_ratio'] for r in rows):.2f}); "
                 f"decode: {statistics.median(r['decode_ratio'] for r in rows):.2f} "
                 f"(CPU {statistics.median(r['decode_cpu_ratio'] for r in rows):.2f}). "
                 f"Load average before and after the run: {meta['load_before']} and {meta['load_after']} "
                 f"(2 cores, shared). psq at {meta['commit']}; `{meta['command']}`.")
    lines.append("")
    return "\n".join(lines)


def readme_table(rows, meta):
    enc = [r["encode_ratio"] for r in rows]
    dec = [r["decode_ratio"] for r in rows]
    lines = [
        f"Whole process, file to file ({meta['date']}, bench/run_convert_compare.py on {len(rows)} meshes of "
        f"{fmt_int(min(r['triangles'] for r in rows))} to {fmt_int(max(r['triangles'] for r in rows))} triangles, "
        f"{meta['bits']} bits; speed of psq / speed of Draco's tool):",
        "",
        "|  | median | range | median, processor time |",
        "|---|---:|---:|---:|",
        f"| `psq convert X.ply X.psq` / `draco_encoder -cl 7` | {statistics.median(enc):.2f} | {min(enc):.2f}–{max(enc):.2f} | "
        f"{statistics.median(r['encode_cpu_ratio'] for r in rows):.2f} |",
        f"| `psq convert X.psq Y.ply` / `draco_decoder` | {statistics.median(dec):.2f} | {min(dec):.2f}–{max(dec):.2f} | "
        f"{statistics.median(r['decode_cpu_ratio'] for r in rows):.2f} |",
        "",
    ]
    return "\n".join(lines)


def replace_region(text, markers, body, after):
    begin, end = markers
    region = f"{begin}\n{body}{end}"
    if begin in text and end in text:
        a = text.index(begin)
        b = text.index(end) + len(end)
        return text[:a] + region + text[b:]
    if after not in text:
        raise Failure(f"cannot place the region: '{after}' not found")
    at = text.index(after)
    if after.startswith("## "):
        # After the whole section: at the next marker or heading of its level.
        nxt = [i for i in (text.find("\n<!--", at), text.find("\n## ", at + 1)) if i >= 0]
        at = min(nxt) + 1 if nxt else len(text)
        return text[:at] + region + "\n\n" + text[at:]
    at += len(after)
    return text[:at] + "\n\n" + region + text[at:]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("meshes", nargs="*", metavar="MESH.ply")
    ap.add_argument("--build", default=os.path.join(root, "build-bench"))
    ap.add_argument("--sizes", default="1M 10M")
    ap.add_argument("--no-shared", action="store_true")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--bits", type=int, default=14)
    ap.add_argument("--work")
    ap.add_argument("--json")
    ap.add_argument("--write-results", action="store_true")
    ap.add_argument("--results", default=os.path.join(here, "RESULTS.md"))
    ap.add_argument("--readme", default=os.path.join(root, "README.md"))
    args = ap.parse_args()
    if args.rounds < 1 or not 1 <= args.bits <= 30:
        ap.error("--rounds must be at least 1 and --bits within 1..30")
    for tool in ("draco_encoder", "draco_decoder"):
        if shutil.which(tool) is None:
            raise Failure(f"{tool} not found in PATH")
    if not os.path.exists(os.path.join(args.build, "psq")):
        raise Failure(f"{args.build}/psq not found")
    work = args.work or tempfile.mkdtemp(prefix="psq-convert-compare-")
    os.makedirs(work, exist_ok=True)
    try:
        load_before = " ".join(f"{x:.2f}" for x in os.getloadavg())
        rows = []
        for name, path, _origin in meshes_to_run(args, work):
            row = measure(args, name, path, work)
            rows.append(row)
            print(f"{name}: {fmt_int(row['triangles'])} triangles; encode psq {row['encode_psq_seconds']:.3f} s, "
                  f"Draco {row['encode_draco_seconds']:.3f} s, ratio {row['encode_ratio']:.2f}; decode psq "
                  f"{row['decode_psq_seconds']:.3f} s, Draco {row['decode_draco_seconds']:.3f} s, ratio "
                  f"{row['decode_ratio']:.2f}; RSS {row['encode_psq_rss_mib']:.0f}/{row['encode_draco_rss_mib']:.0f} "
                  f"MiB", flush=True)
        load_after = " ".join(f"{x:.2f}" for x in os.getloadavg())
    finally:
        if not args.work:
            shutil.rmtree(work, ignore_errors=True)
    commit = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip() or "unknown"
    shown, skip = [], False
    for a in sys.argv[1:]:
        if skip:
            skip = False
        elif a in ("--work", "--json", "--results", "--readme"):
            skip = True
        elif not a.startswith(("--work=", "--json=", "--results=", "--readme=")):
            shown.append(a)
    command = "bench/run_convert_compare.py " + " ".join(shown)
    meta = {"date": datetime.date.today().isoformat(), "bits": args.bits, "rounds": args.rounds,
            "load_before": load_before, "load_after": load_after, "commit": commit, "command": command.strip(),
            "machine": platform.processor() or platform.machine()}
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"meta": meta, "rows": rows}, f, indent=1)
    print()
    print(table(rows, meta))
    if args.write_results:
        body = "<!-- Generated by bench/run_convert_compare.py --write-results; rerunning it rewrites this region. -->\n\n"
        body += table(rows, meta)
        with open(args.results) as f:
            text = f.read()
        text = replace_region(text, MARKERS, body, SECTION_AFTER)
        with open(args.results, "w") as f:
            f.write(text)
        if os.path.exists(args.readme):
            with open(args.readme) as f:
                text = f.read()
            if README_AFTER in text or README_MARKERS[0] in text:
                body = "<!-- Generated by bench/run_convert_compare.py --write-results. -->\n\n" + readme_table(rows, meta)
                text = replace_region(text, README_MARKERS, body, README_AFTER)
                with open(args.readme, "w") as f:
                    f.write(text)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except (Failure, subprocess.CalledProcessError) as e:
        print(f"run_convert_compare: {e}", file=sys.stderr)
        sys.exit(1)
