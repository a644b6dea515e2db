#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The simplification benchmark: psq's simplifiers beside meshoptimizer's.

Runs every simplifier as a process of its own (so that its peak memory is
its own; /usr/bin/time gives the wall time and the peak resident set) on
the shared meshes (../shared/data/meshes beside the repository, when
present) and on foam-ball meshes from psq-meshgen (--sizes, default 1M),
at each --ratios of the input's triangles (default 10% and 1%), and, for
every psq row, meshoptimizer again at the count psq reached (the equal-
output-count rows, marked "= METHOD"). Then measures each output:

  - the error: psq distance IN OUT --json (Metro: symmetric RMS and
    Hausdorff distance, relative to the diagonal of IN's bounding box);
  - psq info --json OUT: non-manifold vertices and edges, border edges,
    components;
  - psq_simplify_compare quality IN OUT: degenerate triangles (a repeated
    corner or zero area) and flipped ones (normal more than 90 degrees
    from the nearest input triangle's, unless an input triangle facing
    its way is about as near: between the sides of a thin wall; see
    simplify_compare.cpp).

psq's methods are found by `psq simplify --methods`, else by the
"Methods (--method):" list of `psq simplify --help`, or given by --methods;
when the tool has no simplify command there are no psq rows. meshoptimizer
rows report meshoptimizer's own figures: the index count it returned (the
run stops if the output file disagrees) and its result_error (relative to
meshopt_simplifyScale, the largest extent of the box).

  bench/run_simplify_compare.py [--build DIR] [--sizes "1M 10M 50M"] [--no-shared]
      [--ratios 0.1,0.01] [--methods "clustering qem"] [--work DIR]
      [--json FILE] [--write-results] [--results FILE] [--plot FILE] [MESH]...
  bench/run_simplify_compare.py --build build-bench --write-results   # what bench/RESULTS.md shows

--write-results rewrites the region of bench/RESULTS.md between
<!-- simplify:begin --> and <!-- simplify:end --> (added at the end of the
file the first time) and bench/simplify_compare.png (gnuplot, pngcairo);
nothing is written if the run fails. The tools come from --build (psq,
psq-meshgen, bench/psq_simplify_compare: configure with
-DPSQ_BUILD_BENCH=ON).
"""

import argparse
import datetime
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

MARKERS = ("<!-- simplify:begin -->", "<!-- simplify:end -->")
MESHOPT = ("meshopt_simplify", "meshopt_simplifySloppy")


class Failure(Exception):
    pass


def run(cmd, timed=False):
    """Runs cmd; returns (stdout, seconds, peak KiB): with `timed`, the wall
    time (measured here, finer than /usr/bin/time's hundredths) and the
    peak resident set (/usr/bin/time's %M). Raises Failure on a non-zero
    exit."""
    peak = None
    seconds = None
    if timed:
        with tempfile.NamedTemporaryFile("r", suffix=".time") as t:
            full = ["/usr/bin/time", "-f", "%M", "-o", t.name] + cmd
            t0 = time.perf_counter()
            p = subprocess.run(full, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            seconds = time.perf_counter() - t0
            fields = t.read().split()
            if fields and p.returncode == 0:
                peak = int(fields[-1])
    else:
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise Failure("%s: exit %d: %s" % (" ".join(cmd), p.returncode, p.stderr.strip()[-400:]))
    return p.stdout, seconds, peak


def json_of(cmd):
    out, _, _ = run(cmd)
    return json.loads(out)


def psq_methods(psq, given):
    """psq simplify's methods: --methods, `psq simplify --methods`, or the
    "Methods (--method):" list of its --help; [] without the command."""
    if given is not None:
        return given.split()
    p = subprocess.run([psq, "simplify", "--methods"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode == 0 and p.stdout.strip():
        return p.stdout.split()
    p = subprocess.run([psq, "simplify", "--help"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        return []
    methods, inside = [], False
    for line in p.stdout.splitlines():
        if line.startswith("Methods"):
            inside = True
            continue
        if inside:
            if not line.strip():
                break
            m = re.match(r"^  ([a-z][a-z0-9_-]*)(\s{2,}|$)", line)
            if m:
                methods.append(m.group(1))
    return methods


def count_text(n):
    """1.2M, 69.5k, 512."""
    for div, suffix in ((1000000, "M"), (1000, "k")):
        if n >= div:
            return "%.3g%s" % (n / div, suffix)
    return str(n)


class Bench:
    def __init__(self, args):
        self.args = args
        b = os.path.abspath(args.build)
        self.psq = os.path.join(b, "psq")
        self.meshgen = os.path.join(b, "psq-meshgen")
        self.tool = os.path.join(b, "bench", "psq_simplify_compare")
        for t in (self.psq, self.meshgen, self.tool):
            if not os.access(t, os.X_OK):
                raise Failure("%s not found: configure with -DPSQ_BUILD_BENCH=ON and build it" % t)
        self.work = args.work
        self.methods = psq_methods(self.psq, args.methods)
        self.rows = []
        self.meshopt_version = "?"

    def measure(self, src, out, row):
        """Error, topology and triangle counts of `out`, into row. An empty
        output has no surface to measure: its error and topology stay None."""
        q = json_of([self.tool, "quality", src, out])
        row["triangles"] = q["triangles"]
        row["vertices"] = q["vertices"]
        row["degenerate"] = q["degenerate_triangles"]
        row["flipped"] = q["flipped_triangles"]
        for k in ("rms", "hausdorff", "nonmanifold_vertices", "nonmanifold_edges", "border_edges", "components"):
            row[k] = None
        if q["triangles"] == 0:
            return
        d = json_of([self.psq, "distance", "--json", src, out])
        row["rms"] = d["relative"]["symmetric"]["rms"]
        row["hausdorff"] = d["relative"]["hausdorff"]
        row["distance_seconds"] = d["timing"]["seconds"]
        info = json_of([self.psq, "info", "--json", out])
        for k in ("nonmanifold_vertices", "nonmanifold_edges", "border_edges", "components"):
            row[k] = info[k]
        if info["triangles"] != q["triangles"]:
            raise Failure("%s: psq info counts %d triangles, the quality pass %d" % (out, info["triangles"], q["triangles"]))

    def meshopt(self, mesh, src, name, target, label):
        out = os.path.join(self.work, "out.ply")
        cmd = [self.tool, "meshopt"] + (["--sloppy"] if name == "meshopt_simplifySloppy" else []) + \
              [src, out, "--triangles", str(target)]
        text, seconds, peak = run(cmd, timed=True)
        r = json.loads(text)
        v = r["meshoptimizer_version"]  # 1000 major + 10 minor + patch
        self.meshopt_version = "%d.%d" % (v // 1000, v // 10 % 100) + (".%d" % (v % 10) if v % 10 else "")
        row = {"mesh": mesh["name"], "method": name, "target": label, "target_triangles": target,
               "seconds": seconds, "peak_kib": peak, "result_error": r["result_error"],
               "result_index_count": r["result_index_count"], "simplify_seconds": r["seconds_simplify"]}
        self.measure(src, out, row)
        # meshoptimizer's own count, reproduced from the file it wrote.
        if r["result_index_count"] != 3 * row["triangles"]:
            raise Failure("%s on %s: meshoptimizer returned %d indices, the output has %d triangles" %
                          (name, mesh["name"], r["result_index_count"], row["triangles"]))
        return row

    def psq_simplify(self, mesh, src, method, target, label):
        out = os.path.join(self.work, "out.ply")
        cmd = [self.psq, "simplify", src, out, "--method", method, "--triangles", str(target), "-f", "-q"]
        row = {"mesh": mesh["name"], "method": "psq " + method, "target": label, "target_triangles": target}
        try:
            _, row["seconds"], row["peak_kib"] = run(cmd, timed=True)
        except Failure as e:
            row["error"] = str(e)
            print("run_simplify_compare: %s" % e, file=sys.stderr)
            return row
        self.measure(src, out, row)
        return row

    def mesh(self, name, src):
        info = json_of([self.psq, "info", "--json", src])
        mesh = {"name": name, "path": src, "triangles": info["triangles"], "vertices": info["vertices"]}
        print("run_simplify_compare: %s (%d triangles)" % (name, mesh["triangles"]), file=sys.stderr)
        for ratio in self.args.ratios:
            target = max(4, int(round(ratio * mesh["triangles"])))
            label = "%g%%" % (100 * ratio)
            for name_ in MESHOPT:
                self.rows.append(self.meshopt(mesh, src, name_, target, label))
            for method in self.methods:
                row = self.psq_simplify(mesh, src, method, target, label)
                self.rows.append(row)
                reached = row.get("triangles")
                # meshoptimizer at the count psq reached: errors at equal output sizes.
                if reached and reached != target:
                    for name_ in MESHOPT:
                        self.rows.append(self.meshopt(mesh, src, name_, reached, "= " + method))
        return mesh

    def run(self):
        meshes = []
        started = time.time()
        inputs = list(self.args.mesh)
        if not self.args.no_shared and os.path.isdir(self.args.shared):
            inputs += sorted(os.path.join(self.args.shared, f) for f in os.listdir(self.args.shared)
                             if re.search(r"\.(ply|obj|off|stl|psq|drc)$", f, re.IGNORECASE))
        for path in inputs:
            meshes.append(self.mesh(os.path.basename(path), os.path.abspath(path)))
        for size in self.args.sizes.split():
            path = os.path.join(self.work, "foam_%s.ply" % size)
            t0 = time.time()
            run([self.meshgen, "--triangles", size, "-o", path, "-f", "-q"])
            gen = time.time() - t0
            m = self.mesh("foam_%s.ply" % size, path)
            m["generated_seconds"] = gen
            meshes.append(m)
            os.remove(path)
        return {"meshes": meshes, "rows": self.rows, "methods": self.methods,
                "meshopt_version": self.meshopt_version, "seconds": time.time() - started}


# ------------------------------------------------------------ the results

def fmt_err(v):
    return "%.2e" % v if v is not None else "-"


def fmt_int(v):
    return "%d" % v if v is not None else "-"


def table(data):
    """The Markdown table, one block of rows a mesh."""
    head = ("| mesh | method | target | triangles | vertices | RMS / diag | Hausdorff / diag | meshopt "
            "result_error | non-manifold v / e | degenerate | flipped | border edges | components | "
            "seconds | M input tri/s | peak MiB |")
    lines = [head, "|" + "---|" * 16]
    by_mesh = {}
    for r in data["rows"]:
        by_mesh.setdefault(r["mesh"], []).append(r)
    for m in data["meshes"]:
        first = True
        for r in by_mesh.get(m["name"], []):
            name = "%s (%s)" % (m["name"], "{:,}".format(m["triangles"])) if first else ""
            first = False
            if "error" in r:
                lines.append("| %s | %s | %s | failed |%s" % (name, r["method"], r["target"], " |" * 12))
                continue
            rate = m["triangles"] / r["seconds"] / 1e6 if r.get("seconds") else None
            lines.append("| %s | %s | %s | %d | %d | %s | %s | %s | %s / %s | %d | %d | %s | %s | %s | %s | %s |" % (
                name, r["method"], r["target"], r["triangles"], r["vertices"], fmt_err(r["rms"]),
                fmt_err(r["hausdorff"]), fmt_err(r.get("result_error")) if "result_error" in r else "",
                fmt_int(r["nonmanifold_vertices"]), fmt_int(r["nonmanifold_edges"]), r["degenerate"], r["flipped"],
                fmt_int(r["border_edges"]), fmt_int(r["components"]),
                "%.3f" % r["seconds"] if r.get("seconds") is not None else "",
                "%.3g" % rate if rate else "",
                "%.1f" % (r["peak_kib"] / 1024.0) if r.get("peak_kib") else ""))
    return "\n".join(lines)


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return "%s, %d cores" % (cpu, os.cpu_count() or 0)


def section(data, command, plot_name, repo):
    try:
        commit = subprocess.run(["git", "-C", repo, "rev-parse", "--short", "HEAD"], stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True).stdout.strip()
    except OSError:
        commit = "?"
    methods = ", ".join("psq " + m for m in data["methods"]) if data["methods"] else \
        "none (this psq has no simplify command)"
    out = [MARKERS[0],
           "<!-- Generated by bench/run_simplify_compare.py; --write-results rewrites this region and %s. -->" % plot_name,
           "",
           "## Simplification: psq beside meshoptimizer (%s)" % datetime.date.today().isoformat(),
           "",
           "`%s` at %s, %s; %.0f s in all. psq's simplifiers: %s. meshoptimizer %s (Debian's libmeshoptimizer)." % (
               command, commit or "?", machine(), data["seconds"], methods, data.get("meshopt_version", "")),
           "",
           "Each simplifier runs as a process of its own, file to file (PLY in, PLY out): *seconds* and *peak* "
           "are that process's (`/usr/bin/time`), *M input tri/s* the input's triangles over those seconds. "
           "The error is `psq distance IN OUT` (Metro: 10 samples a triangle on each side, at most 4M, every "
           "vertex included; the larger RMS and Hausdorff distance of the two directions, over the diagonal "
           "of the input's bounding box). *meshopt result_error* is meshoptimizer's own estimate (relative to "
           "its `meshopt_simplifyScale`, the largest extent of the box); its *triangles* are the index count it "
           "returned, over 3, checked against the file it wrote. Non-manifold vertices and edges, border edges "
           "and components are `psq info`'s; degenerate triangles repeat a corner or have zero area; flipped "
           "ones have a normal more than 90 degrees from that of the input triangle nearest to their "
           "centroid, unless an input triangle facing within 90 degrees of theirs is within twice that "
           "distance plus a tenth of their longest edge (between the two sides of a thin wall, both about "
           "as near as the error, the nearest side does not tell which side a triangle stands for; a "
           "triangle turned over on a side is still counted). Targets: a share of the input's triangles, or \"= METHOD\": the count that psq METHOD "
           "reached, for errors at equal output sizes.",
           "",
           "![Error against output size](%s)" % plot_name,
           "",
           table(data),
           ""]
    gens = [m for m in data["meshes"] if "generated_seconds" in m]
    if gens:
        out.append("foam_N.ply: `psq-meshgen --triangles N` (seed 1, coherent order); " + "; ".join(
            "%s: %s triangles, %.1f s to generate" % (m["name"], "{:,}".format(m["triangles"]), m["generated_seconds"])
            for m in gens) + ".")
        out.append("")
    out.append(MARKERS[1])
    return "\n".join(out)


def plot(data, path):
    """Relative RMS error against output triangles, a panel a mesh, a curve a
    method (gnuplot, pngcairo)."""
    if not shutil.which("gnuplot"):
        raise Failure("gnuplot not found (Debian: gnuplot-nox)")
    methods = []
    for r in data["rows"]:
        if r["method"] not in methods:
            methods.append(r["method"])
    meshes = [m for m in data["meshes"] if any(r["mesh"] == m["name"] and (r.get("rms") or 0) > 0
                                               for r in data["rows"])]
    cols = min(6, max(1, len(meshes)))
    nrows = (len(meshes) + cols - 1) // cols
    with tempfile.TemporaryDirectory() as tmp:
        script = ["set terminal pngcairo size %d,%d font 'sans,9'" % (380 * cols, 300 * nrows + 40),
                  "set output '%s'" % path,
                  "set multiplot layout %d,%d title 'Symmetric RMS distance / diagonal against output triangles "
                  "(log-log)'" % (nrows, cols),
                  "set logscale xy", "set format x '%.0s%c'", "set format y '10^{%L}'", "set grid",
                  "set key top right font 'sans,7'"]
        styles = ["lc rgb '#1b9e77' pt 7", "lc rgb '#d95f02' pt 5", "lc rgb '#7570b3' pt 9",
                  "lc rgb '#e7298a' pt 11", "lc rgb '#66a61e' pt 13", "lc rgb '#e6ab02' pt 15"]
        for i, m in enumerate(meshes):
            plots = []
            for j, method in enumerate(methods):
                pts = sorted((r["triangles"], r["rms"]) for r in data["rows"]
                             if r["mesh"] == m["name"] and r["method"] == method and (r.get("rms") or 0) > 0)
                if not pts:
                    continue
                f = os.path.join(tmp, "%d_%d.dat" % (i, j))
                with open(f, "w") as out:
                    out.write("".join("%d %.9g\n" % p for p in pts))
                plots.append("'%s' using 1:2 with linespoints %s title '%s'" % (
                    f, styles[j % len(styles)], method.replace("_", "\\_") if i == 0 else ""))
            script.append("set title '%s (%s)'" % (m["name"].replace("_", "\\_"), count_text(m["triangles"])))
            script.append("unset key" if i else "set key")
            script.append("plot " + ", ".join(plots) if plots else "plot NaN notitle")
        script.append("unset multiplot")
        sf = os.path.join(tmp, "plot.gp")
        with open(sf, "w") as f:
            f.write("\n".join(script) + "\n")
        p = subprocess.run(["gnuplot", sf], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if p.returncode != 0:
            raise Failure("gnuplot: " + p.stderr.strip()[-400:])


def replace_section(results, text):
    with open(results) as f:
        old = f.read()
    if MARKERS[0] in old and MARKERS[1] in old:
        a = old.index(MARKERS[0])
        b = old.index(MARKERS[1]) + len(MARKERS[1])
        new = old[:a] + text + old[b:]
    else:
        new = old.rstrip("\n") + "\n\n" + text + "\n"
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(results)))
    with os.fdopen(fd, "w") as f:
        f.write(new)
    os.replace(tmp, results)


def main():
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(repo, "build"))
    ap.add_argument("--sizes", default="1M")
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(repo), "shared", "data", "meshes"))
    ap.add_argument("--no-shared", action="store_true")
    ap.add_argument("--ratios", default="0.1,0.01")
    ap.add_argument("--methods", default=None, help="psq simplify methods (default: ask psq simplify)")
    ap.add_argument("--work", default=None, help="directory for generated meshes and outputs (default: a temporary one)")
    ap.add_argument("--json", default=None, help="also write the rows to this file")
    ap.add_argument("--write-results", action="store_true")
    ap.add_argument("--results", default=None)
    ap.add_argument("--plot", default=None)
    ap.add_argument("mesh", nargs="*")
    args = ap.parse_args()
    args.ratios = [float(r) for r in args.ratios.split(",") if r]
    if args.results or args.plot:
        args.write_results = True
    results = args.results or os.path.join(repo, "bench", "RESULTS.md")
    plot_path = args.plot or os.path.join(os.path.dirname(os.path.abspath(results)), "simplify_compare.png")
    command = "bench/run_simplify_compare.py " + " ".join(
        a if re.match(r"^[A-Za-z0-9_./,:=+@%-]+$", a) else "'%s'" % a for a in sys.argv[1:])
    if args.write_results and not os.access(results, os.W_OK):
        print("run_simplify_compare: %s is not writable" % results, file=sys.stderr)
        return 2
    own_work = args.work is None
    if own_work:
        args.work = tempfile.mkdtemp(prefix="psq-simplify-")
    try:
        bench = Bench(args)
        data = bench.run()
    except Failure as e:
        print("run_simplify_compare: %s" % e, file=sys.stderr)
        return 1
    finally:
        if own_work:
            shutil.rmtree(args.work, ignore_errors=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(data, f, indent=1)
    print(table(data))
    if args.write_results:
        plot_name = os.path.basename(plot_path)
        try:
            tmp_png = plot_path + ".tmp.png"
            plot(data, tmp_png)
            replace_section(results, section(data, command, plot_name, repo))
            os.replace(tmp_png, plot_path)
        except (Failure, OSError) as e:
            print("run_simplify_compare: %s" % e, file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
