#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Writes the codec comparison of bench/RESULTS.md from psq_bench_compare --json.

The JSON is the only source of numbers. The Markdown goes between the lines
`<!-- compare:begin -->` and `<!-- compare:end -->` of the results file; the
rest of the file is kept byte for byte. With --readme, the headline goes
between `<!-- bench-headline:begin -->` and `<!-- bench-headline:end -->` of
that file too. Every file is written to a temporary file beside it and
renamed, so a failure leaves it as it was.

  bench/make_results.py --json compare.json [--json more.json] --build build \\
      --results bench/RESULTS.md [--readme README.md] [--command "..."]...
  bench/make_results.py --check --results bench/RESULTS.md [--readme README.md]

bench/run_compare.sh --write-results runs the comparison and then this script.
Several --json files are merged mesh by mesh (the first file that has a codec
on a mesh gives its numbers). See bench/compare_README.md.
"""

import argparse
import datetime
import glob
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile

COMPARE_MARKERS = ("<!-- compare:begin -->", "<!-- compare:end -->")
HEADLINE_MARKERS = ("<!-- bench-headline:begin -->", "<!-- bench-headline:end -->")
LARGE_TRIANGLES = 200000  # the speed table's threshold
LOSSLESS = None           # quantization key of lossless codecs


class Failure(Exception):
    pass


# ---------------------------------------------------------------- the data

def quantization(codec):
    """Bits of the position grid (11, 14, 16), or LOSSLESS."""
    m = re.search(r"-q(\d+)", codec)
    return int(m.group(1)) if m else LOSSLESS


def psq_reference(codec):
    """The psq codec at the same quantization as `codec`."""
    q = quantization(codec)
    return "psq-lossless" if q is LOSSLESS else "psq-q%d" % q


def is_psq(codec):
    return codec.startswith("psq-")


def is_encoder_alone(codec):
    """psq-qN-seq: the same bytes as psq-qN, its encoder timed alone on a
    recorded processing sequence (the codec issue's encode criterion)."""
    return codec.endswith("-seq")


def display_mesh(name):
    return re.sub(r"\.(ply|obj)$", "", name, flags=re.IGNORECASE)


def load(paths):
    """Merges the JSON files: returns (meshes, codec order, sources)."""
    meshes = {}   # mesh name -> {"vertices", "triangles", "runs", "codecs": {name: entry}}
    order = []    # mesh names in first-seen order
    codecs = []   # codec names in first-seen order
    sources = []
    for path in paths:
        try:
            with open(path) as f:
                data = json.load(f)
        except (OSError, ValueError) as e:
            raise Failure("%s: %s" % (path, e))
        if not isinstance(data, dict) or not isinstance(data.get("meshes"), list):
            raise Failure("%s: not the JSON of psq_bench_compare" % path)
        sources.append({"path": path, "runs": data.get("runs"), "draco": data.get("draco"),
                        "zstd": data.get("zstd"), "meshoptimizer": data.get("meshoptimizer"),
                        "mtime": os.path.getmtime(path)})
        for m in data["meshes"]:
            name = m["mesh"]
            if name not in meshes:
                meshes[name] = {"vertices": m["vertices"], "triangles": m["triangles"],
                                "float64": m.get("float64_positions", False),
                                "runs": {}, "codecs": {}}
                order.append(name)
            mesh = meshes[name]
            if (mesh["vertices"], mesh["triangles"]) != (m["vertices"], m["triangles"]):
                raise Failure("%s: %s has other counts than in an earlier file" % (path, name))
            for c in m["codecs"]:
                if c["codec"] in mesh["codecs"]:
                    continue
                mesh["codecs"][c["codec"]] = c
                mesh["runs"][c["codec"]] = data.get("runs")
                if c["codec"] not in codecs:
                    codecs.append(c["codec"])
    if not order:
        raise Failure("no mesh in %s" % ", ".join(paths))
    return meshes, order, codecs, sources


def column_order(codecs):
    """Grouped by quantization (11, 14, 16, then lossless), psq first in
    each, then by name with numbers compared as numbers (cl7 before cl10)."""
    def key(c):
        q = quantization(c)
        natural = [(0, int(t), "") if t.isdigit() else (1, 0, t) for t in re.findall(r"\d+|\D+", c)]
        return (q is LOSSLESS, q or 0, not is_psq(c), natural)
    return sorted(codecs, key=key)


def entry(mesh, codec):
    """The codec's entry on the mesh if it succeeded, else None."""
    c = mesh["codecs"].get(codec)
    return c if c and c.get("ok") else None


def size_ratio(mesh, codec, ref):
    a, b = entry(mesh, codec), entry(mesh, ref)
    if not a or not b or not b["bytes"]:
        return None
    return a["bytes"] / b["bytes"]


def rate(mesh, c, direction):
    s = c.get(direction + "_median_seconds") or 0
    return mesh["triangles"] / s / 1e6 if s > 0 else None


def peak_mib(c, direction):
    k = c.get(direction + "_peak_kib", -1)
    return k / 1024.0 if k is not None and k >= 0 else None


# ------------------------------------------------------------- formatting

def f_bpv(v):
    return "-" if v is None else "%.1f" % v


def f_ratio(v):
    return "-" if v is None else "%.3f" % v


def f_speed_ratio(v):
    """A speed ratio with two decimals, or "-" when it could not be computed (NaN)."""
    return "-" if v is None or v != v else "%.2f" % v


def f_rate(v):
    if v is None:
        return "-"
    return "%.3g" % v if v < 1000 else "%.0f" % v


def f_mib(v):
    return "-" if v is None else "%.1f" % v


def f_times(v):
    return "-" if v is None else "%.2f" % v


def table(header, rows, numeric_from, text=()):
    """A Markdown table; columns from `numeric_from` on are right-aligned,
    except those named in `text`."""
    out = ["| " + " | ".join(header) + " |",
           "|" + "|".join("---:" if i >= numeric_from and header[i] not in text else "---"
                          for i in range(len(header))) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def span(values, fmt):
    values = [v for v in values if v is not None]
    if not values:
        return "-"
    lo, hi = min(values), max(values)
    return fmt(lo) if fmt(lo) == fmt(hi) else "%s–%s" % (fmt(lo), fmt(hi))


# ------------------------------------------------------------ the machine

def read_text(path):
    try:
        with open(path, errors="replace") as f:
            return f.read()
    except OSError:
        return ""


def machine():
    cpuinfo = read_text("/proc/cpuinfo")
    m = re.search(r"^model name\s*:\s*(.+)$", cpuinfo, re.M)
    cpu = m.group(1).strip() if m else (platform.processor() or "unknown CPU")
    logical = len(re.findall(r"^processor\s*:", cpuinfo, re.M)) or os.cpu_count() or 0
    try:
        usable = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        usable = logical
    cores = "%d cores" % logical + ("" if usable == logical else " (%d usable)" % usable)
    m = re.search(r"^MemTotal:\s*(\d+) kB", read_text("/proc/meminfo"), re.M)
    memory = "%.1f GiB" % (int(m.group(1)) / 1048576.0) if m else "unknown memory"
    m = re.search(r'^PRETTY_NAME="?([^"\n]*)"?', read_text("/etc/os-release"), re.M)
    system = m.group(1) if m else platform.system()
    return "%s, %s, %s, %s (Linux %s)" % (cpu, cores, memory, system, platform.release())


def compiler(build):
    cache = read_text(os.path.join(build, "CMakeCache.txt"))
    if not cache:
        return "unknown (no %s/CMakeCache.txt)" % build

    def var(name):
        m = re.search(r"^%s:[A-Z]+=(.*)$" % re.escape(name), cache, re.M)
        return m.group(1).strip() if m else ""

    path = var("CMAKE_CXX_COMPILER")
    build_type = var("CMAKE_BUILD_TYPE") or "no build type"
    flags = " ".join(f for f in (var("CMAKE_CXX_FLAGS"),
                                 var("CMAKE_CXX_FLAGS_" + build_type.upper())) if f)
    ident = ""
    for cmake in sorted(glob.glob(os.path.join(build, "CMakeFiles", "*", "CMakeCXXCompiler.cmake"))):
        text = read_text(cmake)
        i = re.search(r'set\(CMAKE_CXX_COMPILER_ID "([^"]*)"\)', text)
        v = re.search(r'set\(CMAKE_CXX_COMPILER_VERSION "([^"]*)"\)', text)
        if i and v:
            ident = "%s %s " % (i.group(1), v.group(1))
    return "%s(`%s`), %s, `%s`" % (ident, path, build_type, flags or "no flags")


def revision(repo):
    def git(*args):
        return subprocess.run(["git", "--no-optional-locks", "-C", repo] + list(args),
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        head = git("rev-parse", "--short=12", "HEAD")
        if head.returncode != 0:
            return None
        dirty = git("diff", "--quiet", "HEAD", "--").returncode != 0
    except OSError:
        return None
    return "commit " + head.stdout.strip() + (" with uncommitted changes" if dirty else "")


def versions(sources):
    def one(key, fmt):
        seen = []
        for s in sources:
            v = s.get(key)
            if v is not None and fmt(v) not in seen:
                seen.append(fmt(v))
        return " / ".join(seen) if seen else "?"
    meshopt = lambda v: "%d.%d" % (v // 1000, v // 10 % 100) if isinstance(v, int) else str(v)
    return "Draco %s, zstd %s, meshoptimizer %s" % (one("draco", str), one("zstd", str),
                                                    one("meshoptimizer", meshopt))


# -------------------------------------------------------------- the region

def generated(name):
    """The meshes run_compare.sh generates with psq-meshgen (foam_<size>.ply)."""
    return name.startswith("foam_")


def headline(meshes, order, codecs, shared_only=False, profile=""):
    """Numbers for the summary: per bits, (median psq/Draco cl7, smaller, n),
    over every mesh or, with shared_only, over the meshes not generated by
    psq-meshgen (the shared test meshes: the codec issue's size criterion).
    `profile` "" gives the adaptive back-end's codecs (psq-qN), "fast-" the
    rANS back-end's (psq-fast-qN)."""
    sizes = []
    for bits in (11, 14, 16):
        psq, draco = "psq-%sq%d" % (profile, bits), "draco-q%d-cl7" % bits
        ratios = [size_ratio(meshes[n], psq, draco) for n in order if not (shared_only and generated(n))]
        ratios = [r for r in ratios if r is not None]
        if ratios:
            sizes.append((bits, statistics.median(ratios), sum(r < 1 for r in ratios), len(ratios)))
    large = [meshes[n] for n in order if meshes[n]["triangles"] >= LARGE_TRIANGLES]
    name = "psq-%sq16" % profile
    pairs = [(m, entry(m, name), entry(m, "draco-q16-cl7")) for m in large]
    pairs = [(m, p, d) for m, p, d in pairs if p and d]

    def ratio(codec, direction):
        values = [rate(m, entry(m, codec), direction) / rate(m, d, direction) for m, p, d in pairs
                  if entry(m, codec) and rate(m, entry(m, codec), direction) and rate(m, d, direction)]
        return statistics.median(values) if values else float("nan")

    def rates(codec, direction):
        return span([rate(m, entry(m, codec), direction) for m, p, d in pairs if entry(m, codec)], f_rate)

    speed = None
    if pairs:
        speed = {
            "n": len(pairs),
            "psq_dec": span([rate(m, p, "decode") for m, p, d in pairs], f_rate),
            "draco_dec": span([rate(m, d, "decode") for m, p, d in pairs], f_rate),
            "psq_enc": span([rate(m, p, "encode") for m, p, d in pairs], f_rate),
            "psq_enc_seq": rates(name + "-seq", "encode"),
            "enc_seq_ratio": ratio(name + "-seq", "encode"),
            "psq_dec_arrays": rates(name + "-arrays", "decode"),
            "dec_arrays_ratio": ratio(name + "-arrays", "decode"),
            "draco_enc": span([rate(m, d, "encode") for m, p, d in pairs], f_rate),
            "psq_peak": span([peak_mib(p, "decode") for m, p, d in pairs], f_mib),
            "draco_peak": span([peak_mib(d, "decode") for m, p, d in pairs], f_mib),
            "dec_ratio": statistics.median(
                [rate(m, p, "decode") / rate(m, d, "decode") for m, p, d in pairs
                 if rate(m, p, "decode") and rate(m, d, "decode")] or [float("nan")]),
        }
    return sizes, speed


def utc(t):
    return datetime.datetime.fromtimestamp(t, datetime.timezone.utc)


def region(meshes, order, codecs, sources, build, commands, note, rev):
    when = utc(max(s["mtime"] for s in sources))
    first = utc(min(s["mtime"] for s in sources))
    cols = column_order(codecs)
    size_cols = [c for c in cols if not is_encoder_alone(c)]  # -seq: psq-qN's bytes again
    runs = sorted({r for n in order for r in meshes[n]["runs"].values() if r is not None})
    L = []
    L.append("<!-- Generated by bench/make_results.py from psq_bench_compare --json;"
             " bench/run_compare.sh --write-results rewrites this region. -->")
    L.append("")
    L.append("## Codec comparison: psq, Draco, PLY + zstd, meshoptimizer (%s)" % when.strftime("%Y-%m-%d"))
    L.append("")
    if first.strftime("%Y-%m-%d %H:%M") == when.strftime("%Y-%m-%d %H:%M"):
        L.append("- Date: %s (when the JSON was written)" % when.strftime("%Y-%m-%d %H:%M UTC"))
    else:
        L.append("- Date: %s to %s (when the JSON files were written)"
                 % (first.strftime("%Y-%m-%d %H:%M"), when.strftime("%Y-%m-%d %H:%M UTC")))
    L.append("- Machine: %s" % machine())
    L.append("- Compiler: %s" % compiler(build))
    if rev:
        L.append("- psq: %s" % rev)
    L.append("- Libraries: %s" % versions(sources))
    if len(runs) == 1:
        L.append("- Times: %s per codec and direction (`--runs %d`)"
                 % ("one run" if runs[0] == 1 else "medians of %d runs" % runs[0], runs[0]))
    else:
        L.append("- Times: medians of the runs given per mesh in the speed table (`--runs`)")
    if note:
        L.append("- Note: %s" % note)
    L.append("")
    L.append("Command%s:" % ("s" if len(commands) > 1 else ""))
    L.append("")
    L.append("```sh")
    L += commands or ["(not recorded)"]
    L.append("```")
    L.append("")
    L.append("Each mesh is read once into memory (float positions, uint32 triangles); every"
             " codec encodes and decodes it in a forked child (method: `bench/compare_README.md`).")
    L.append("")

    sizes, speed = headline(meshes, order, codecs)
    if sizes or speed:
        L.append("### Summary")
        L.append("")
        shared, _ = headline(meshes, order, codecs, shared_only=True)
        for (bits, median, smaller, n), (_, smedian, ssmaller, sn) in zip(sizes, shared):
            L.append("- %d bits: psq / draco-q%d-cl7 bytes, median over the %d meshes not generated"
                     " by psq-meshgen **%.3f** (psq smaller on %d); over all %d meshes **%.3f**"
                     " (psq smaller on %d)." % (bits, bits, sn, smedian, ssmaller, n, median, smaller))
        if speed:
            L.append("- 16 bits, %d meshes of %dk triangles and more: psq decodes at %s M triangles/s,"
                     " Draco -cl 7 at %s (median psq / Draco **%.2f**); encode from a mesh"
                     " (converter and encoder) %s against %s; the encoder alone, from a recorded"
                     " processing sequence (`psq-q16-seq`), %s (median psq / Draco **%.2f**);"
                     " decoder peak %s MiB against %s MiB."
                     % (speed["n"], LARGE_TRIANGLES // 1000, speed["psq_dec"], speed["draco_dec"],
                        speed["dec_ratio"], speed["psq_enc"], speed["draco_enc"],
                        speed["psq_enc_seq"], speed["enc_seq_ratio"],
                        speed["psq_peak"], speed["draco_peak"]))
        fsizes, fspeed = headline(meshes, order, codecs, profile="fast-")
        fshared = {s[0]: s for s in headline(meshes, order, codecs, shared_only=True, profile="fast-")[0]}
        for bits, median, smaller, n in fsizes:
            shared_part = ""
            if bits in fshared:
                _, smedian, ssmaller, sn = fshared[bits]
                shared_part = (" median over the %d meshes not generated by psq-meshgen **%.3f** (psq smaller"
                               " on %d);" % (sn, smedian, ssmaller))
            L.append("- rANS back-end, %d bits: psq-fast-q%d / draco-q%d-cl7 bytes,%s over all %d meshes"
                     " **%.3f** (psq smaller on %d)." % (bits, bits, bits, shared_part, n, median, smaller))
        if fspeed:
            L.append("- rANS back-end, 16 bits, %d meshes of %dk triangles and more: decoding into arrays"
                     " (`psq-fast-q16-arrays`) at %s M triangles/s (median psq / Draco **%s**); the encoder"
                     " alone (`psq-fast-q16-seq`) at %s (median psq / Draco **%s**); encode from a mesh %s;"
                     " decoder peak %s MiB."
                     % (fspeed["n"], LARGE_TRIANGLES // 1000, fspeed["psq_dec_arrays"],
                        f_speed_ratio(fspeed["dec_arrays_ratio"]), fspeed["psq_enc_seq"], f_speed_ratio(fspeed["enc_seq_ratio"]),
                        fspeed["psq_enc"], fspeed["psq_peak"]))
        L.append("")

    L.append("### Size, bits per input vertex")
    L.append("")
    L.append("`-` where a codec did not run on a mesh, `failed` where it failed. Columns are"
             " grouped by quantization; `ply*` and `psq-lossless` keep float positions bit-exact.")
    L.append("")
    rows = []
    for n in order:
        m = meshes[n]
        row = [display_mesh(n), str(m["vertices"]), str(m["triangles"])]
        for c in size_cols:
            e = m["codecs"].get(c)
            row.append("-" if e is None else ("failed" if not e.get("ok") else f_bpv(e["bits_per_vertex"])))
        rows.append(row)
    L += table(["mesh", "V", "T"] + size_cols, rows, 1)
    L.append("")

    others = [c for c in size_cols if not is_psq(c) and psq_reference(c) in codecs]
    if others:
        L.append("### Size relative to psq at the same quantization")
        L.append("")
        L.append("Each codec's bytes divided by psq's at the same quantization (`psq-qN` for"
                 " `-qN`, `psq-lossless` for the lossless ones): above 1, psq is smaller."
                 " The last row is the median over the meshes.")
        L.append("")
        rows = []
        columns = {c: [] for c in others}
        for n in order:
            row = [display_mesh(n)]
            for c in others:
                r = size_ratio(meshes[n], c, psq_reference(c))
                if r is not None:
                    columns[c].append(r)
                row.append(f_ratio(r))
            rows.append(row)
        rows.append(["**median**"] + ["**%s**" % f_ratio(statistics.median(columns[c])) if columns[c]
                                      else "-" for c in others])
        L += table(["mesh"] + ["%s / %s" % (c, psq_reference(c)) for c in others], rows, 1)
        L.append("")

    large = [n for n in order if meshes[n]["triangles"] >= LARGE_TRIANGLES]
    L.append("### Speed and memory, meshes of %dk triangles and more" % (LARGE_TRIANGLES // 1000))
    L.append("")
    if not large:
        L.append("No mesh of this size in this run.")
        L.append("")
    else:
        L.append("Encode and decode in million triangles per second (median run), peak MiB"
                 " beyond the mesh already in memory (child `ru_maxrss` minus its RSS at fork);"
                 " the last three columns divide by psq's at the same quantization (speed above"
                 " 1: faster than psq; memory above 1: more than psq).")
        L.append("")
        header = ["mesh", "T"] + (["runs"] if len(runs) > 1 else []) + [
            "codec", "enc Mtri/s", "dec Mtri/s", "enc peak MiB", "dec peak MiB",
            "enc / psq", "dec / psq", "dec peak / psq"]
        rows = []
        for n in large:
            m = meshes[n]
            first = True
            for c in cols:
                e = m["codecs"].get(c)
                if e is None:
                    continue
                lead = [display_mesh(n) if first else "", str(m["triangles"]) if first else ""]
                if len(runs) > 1:
                    lead.append(str(m["runs"].get(c)) if first else "")
                first = False
                if not e.get("ok"):
                    rows.append(lead + [c, "failed", "-", f_mib(peak_mib(e, "encode")),
                                        f_mib(peak_mib(e, "decode")), "-", "-", "-"])
                    continue
                ref = entry(m, psq_reference(c))
                enc, dec = rate(m, e, "encode"), rate(m, e, "decode")
                dpeak = peak_mib(e, "decode")

                def over(a, b):
                    return a / b if a is not None and b else None
                if ref is None or (is_psq(c) and not is_encoder_alone(c)):
                    ratios = ["-", "-", "-"] if ref is None else ["1", "1", "1"]
                else:
                    ratios = [f_times(over(enc, rate(m, ref, "encode"))),
                              f_times(over(dec, rate(m, ref, "decode"))),
                              f_times(over(dpeak, peak_mib(ref, "decode")))]
                rows.append(lead + [c, f_rate(enc), f_rate(dec), f_mib(peak_mib(e, "encode")),
                                    f_mib(dpeak)] + ratios)
        L += table(header, rows, 1, text=("codec",))
        L.append("")
    return L


def readme_headline(meshes, order, codecs, sources):
    when = utc(max(s["mtime"] for s in sources))
    sizes, speed = headline(meshes, order, codecs)
    fsizes, fspeed = headline(meshes, order, codecs, profile="fast-")
    L = ["<!-- Generated by bench/run_compare.sh --write-results from the run in bench/RESULTS.md. -->", ""]
    L.append("Latest comparison (%s, `psq_bench_compare` on %d meshes; bench/RESULTS.md has"
             " every number and how it was measured):" % (when.strftime("%Y-%m-%d"), len(order)))
    L.append("")
    # The fast profile's medians by bits, "-" where it did not run.
    fshared = {s[0]: s for s in headline(meshes, order, codecs, shared_only=True, profile="fast-")[0]}
    columns = [s[0] for s in (sizes or fsizes)]
    rows = []
    if sizes:
        shared, _ = headline(meshes, order, codecs, shared_only=True)
        rows += [["size, psq / Draco -cl 7, median of the %d test meshes" % shared[0][3]]
                 + ["%.3f" % s[1] for s in shared],
                 ["test meshes where psq is smaller"] + ["%d of %d" % (s[2], s[3]) for s in shared],
                 ["size, median of all %d meshes (with psq-meshgen foam)" % sizes[0][3]]
                 + ["%.3f" % s[1] for s in sizes]]
    if fshared:
        rows.append(["rANS back-end: size / Draco, median of the test meshes"]
                    + ["%.3f" % fshared[b][1] if b in fshared else "-" for b in columns])
    if rows:
        L += table([""] + ["%d bits" % b for b in columns], rows, 1)
        L.append("")
    # One column per profile that ran on the large meshes, then Draco's.
    profiles = [(name, sp) for name, sp in (("psq adaptive", speed), ("psq rANS", fspeed)) if sp]
    if profiles:
        def row(label, key, draco=None):
            return [label] + [sp[key] for _, sp in profiles] + [draco if draco is not None else "-"]
        first = profiles[0][1]
        rows = [row("encode from a mesh, M triangles/s", "psq_enc", first["draco_enc"]),
                row("encode from a processing sequence (psq's encoder alone)", "psq_enc_seq"),
                row("decode, M triangles/s", "psq_dec", first["draco_dec"]),
                row("decode into vertex and index arrays (decode_mesh)", "psq_dec_arrays"),
                row("decoder peak memory, MiB", "psq_peak", first["draco_peak"])]
        rows.append(["median psq / Draco: decode into arrays; encoder alone"]
                    + ["%s; %s" % (f_speed_ratio(sp["dec_arrays_ratio"]), f_speed_ratio(sp["enc_seq_ratio"])) for _, sp in profiles]
                    + ["1"])
        L += table(["%dk+ triangle meshes (%d), 16 bits" % (LARGE_TRIANGLES // 1000, first["n"])]
                   + [name for name, _ in profiles] + ["Draco -cl 7"], rows, 1)
        L.append("")
    return L


# ------------------------------------------------------------- the files

def split(text, markers, path):
    """(before, after): the text up to and including the begin marker line,
    and from the end marker line on."""
    lines = text.splitlines(keepends=True)
    begin = [i for i, l in enumerate(lines) if l.strip() == markers[0]]
    end = [i for i, l in enumerate(lines) if l.strip() == markers[1]]
    if len(begin) != 1 or len(end) != 1 or end[0] < begin[0]:
        raise Failure("%s: needs one line %s and, after it, one line %s" % (path, markers[0], markers[1]))
    return "".join(lines[:begin[0] + 1]), "".join(lines[end[0]:])


def compose(path, markers, body_lines):
    """The new text of `path`: its region between `markers` replaced."""
    with open(path) as f:
        text = f.read()
    before, after = split(text, markers, path)
    return before + "\n".join(body_lines) + "\n" + after


def write_atomically(path, new):
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=directory)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(new)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, os.stat(path).st_mode & 0o7777)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def main():
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--json", action="append", default=[], help="psq_bench_compare --json output (repeatable)")
    p.add_argument("--results", default=os.path.join(repo, "bench", "RESULTS.md"))
    p.add_argument("--readme", help="also update this file's bench-headline region")
    p.add_argument("--build", default=os.path.join(repo, "build"), help="build directory (compiler from its CMakeCache.txt)")
    p.add_argument("--command", action="append", default=[], help="the command that ran (repeatable)")
    p.add_argument("--note", default="", help="one more line for the header")
    p.add_argument("--revision", help="the psq revision measured (default: git HEAD of this checkout)")
    p.add_argument("--check", action="store_true", help="only check that the files have their markers")
    p.add_argument("--stdout", action="store_true", help="print the region instead of writing files")
    a = p.parse_args()
    try:
        targets = [(a.results, COMPARE_MARKERS)] + ([(a.readme, HEADLINE_MARKERS)] if a.readme else [])
        if not a.stdout:
            for path, markers in targets:
                try:
                    with open(path) as f:
                        split(f.read(), markers, path)
                except OSError as e:
                    raise Failure("%s: %s" % (path, e.strerror))
                if not os.access(os.path.dirname(os.path.abspath(path)), os.W_OK):
                    raise Failure("%s: its directory is not writable" % path)
        if a.check:
            return 0
        if not a.json:
            raise Failure("no --json given")
        meshes, order, codecs, sources = load(a.json)
        rev = a.revision if a.revision is not None else revision(repo)
        body = region(meshes, order, codecs, sources, a.build, a.command, a.note, rev)
        if a.stdout:
            print("\n".join(body))
            return 0
        # Both texts are composed before either file is replaced.
        new = [(a.results, compose(a.results, COMPARE_MARKERS, body))]
        if a.readme:
            new.append((a.readme, compose(a.readme, HEADLINE_MARKERS,
                                          readme_headline(meshes, order, codecs, sources))))
        for path, text in new:
            write_atomically(path, text)
            print("make_results.py: wrote %s" % path, file=sys.stderr)
    except (Failure, OSError, KeyError, TypeError) as e:
        print("make_results.py: %s; nothing written" % (e,), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
