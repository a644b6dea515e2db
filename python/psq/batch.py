# SPDX-License-Identifier: Apache-2.0
"""psq.batch: convert or simplify many mesh files on Dask.

Each file is one task (psq.convert or psq.simplify, which release the GIL)
run on a Dask cluster: a LocalCluster of `workers` processes by default, or
any running scheduler given by address. Results come back as one table, a
row per file (input, output, sizes, seconds, error); a file that fails is
reported in its row and does not stop the others.

From Python::

    rows = psq.batch.convert("scans/*.ply", "out/", workers=4, bits=14)
    rows = psq.batch.simplify(["a.psq", "b.psq"], "small/", method="qem", ratio=0.1)

From the shell::

    python3 -m psq.batch convert 'scans/*.ply' out/ --report report.json
    python3 -m psq.batch simplify scans/ small/ --ratio 0.1 --scheduler tcp://host:8786

The exit status is 0 when every file succeeded, 1 when any failed, 2 for a
usage error. Inputs are a directory (its regular files), a glob pattern,
or a list of paths; outputs go to OUT_DIR under the input's name with the
output format's extension (`to`, default psq).
"""

import argparse
import csv
import glob
import io
import json
import os
import socket
import sys
import time
from typing import Any, Dict, Iterable, List, Optional, Sequence, Union

__all__ = ["convert", "simplify", "run", "expand_inputs", "write_report", "COLUMNS", "main"]

#: The columns of the result table, in order.
COLUMNS = ("input", "output", "ok", "bytes_in", "bytes_out", "triangles_in", "triangles_out", "seconds", "worker",
           "error_code", "error")


def expand_inputs(inputs: Union[str, "os.PathLike[str]", Iterable[Union[str, "os.PathLike[str]"]]]) -> List[str]:
    """The files `inputs` names: a directory's regular files (sorted), a glob's matches (sorted), or a list as given.

    A path that is neither a directory nor has glob characters is taken as one
    file (so that a missing file becomes a failed row rather than nothing).
    """
    if isinstance(inputs, (str, os.PathLike)):
        text = os.fspath(inputs)
        if os.path.isdir(text):
            return sorted(os.path.join(text, n) for n in os.listdir(text)
                          if os.path.isfile(os.path.join(text, n)))
        if glob.has_magic(text):
            return sorted(p for p in glob.glob(text) if not os.path.isdir(p))
        return [text]
    return [os.fspath(p) for p in inputs]


def _outputs(files: Sequence[str], out_dir: str, ext: str) -> List[str]:
    return [os.path.join(out_dir, os.path.splitext(os.path.basename(f))[0] + "." + ext) for f in files]


def _process_one(operation: str, src: str, dst: str, options: Dict[str, Any]) -> Dict[str, Any]:
    """One file, on a worker: never raises; the row says what happened."""
    import psq  # imported on the worker

    row: Dict[str, Any] = {k: None for k in COLUMNS}
    row.update(input=src, output=dst, ok=False, worker=f"{socket.gethostname()}:{os.getpid()}")
    try:
        row["bytes_in"] = os.path.getsize(src)
    except OSError:
        pass
    start = time.perf_counter()
    try:
        if operation == "convert":
            r = psq.convert(src, dst, **options)
            row["triangles_in"] = r.get("triangles")
            row["triangles_out"] = r.get("triangles")
        else:
            r = psq.simplify(src, dst, **options)
            row["triangles_in"] = r.get("input_triangles")
            row["triangles_out"] = r.get("output_triangles")
        row["bytes_out"] = r.get("bytes_out")
        row["ok"] = True
    except psq.Error as e:
        row["error_code"] = e.name
        row["error"] = str(e)
    except Exception as e:  # a bug or an environment problem: still one row
        row["error_code"] = type(e).__name__
        row["error"] = str(e)
    row["seconds"] = round(time.perf_counter() - start, 6)
    return row


def run(operation: str, inputs, out_dir: Union[str, "os.PathLike[str]"], *, scheduler: Optional[str] = None,
        workers: int = 2, client=None, to: str = "psq", report: Optional[Union[str, "os.PathLike[str]"]] = None,
        **options) -> List[Dict[str, Any]]:
    """Runs `operation` ("convert" or "simplify") on every input file with Dask futures.

    scheduler: a Dask scheduler address ("tcp://host:8786"); without one a
    LocalCluster of `workers` single-threaded worker processes is started
    (and closed). client: an existing distributed.Client to use instead.
    options go to psq.convert or psq.simplify (overwrite defaults to False:
    an existing output is a failed row). Returns the rows (COLUMNS), in the
    order of the inputs; writes them to `report` (.json or .csv) if given.
    """
    if operation not in ("convert", "simplify"):
        raise ValueError(f"operation must be 'convert' or 'simplify', not {operation!r}")
    files = expand_inputs(inputs)
    out_dir = os.fspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    outputs = _outputs(files, out_dir, to)
    options = dict(options)
    options.setdefault("overwrite", False)
    options["to"] = to
    if operation == "convert":
        options.setdefault("threads", 1)  # the workers are the parallelism

    rows: List[Optional[Dict[str, Any]]] = [None] * len(files)
    seen: Dict[str, int] = {}
    todo = []
    for i, (src, dst) in enumerate(zip(files, outputs)):
        if dst in seen:  # two inputs of one name in different formats
            row = {k: None for k in COLUMNS}
            row.update(input=src, output=dst, ok=False, error_code="usage",
                       error=f"same output as {files[seen[dst]]}")
            rows[i] = row
        else:
            seen[dst] = i
            todo.append(i)

    start = time.perf_counter()
    if todo:
        own_client = None
        if client is None:
            from distributed import Client, LocalCluster
            if scheduler:
                own_client = Client(scheduler)
            else:
                cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=40)
                own_client = Client(cluster)
            client = own_client
        try:
            futures = client.map(_process_one, [operation] * len(todo), [files[i] for i in todo],
                                 [outputs[i] for i in todo], [options] * len(todo), pure=False)
            for i, row in zip(todo, client.gather(futures)):
                rows[i] = row
        finally:
            if own_client is not None:
                cluster = getattr(own_client, "cluster", None)
                own_client.close()
                if cluster is not None:
                    cluster.close()
    result = [r for r in rows if r is not None]
    if report is not None:
        write_report(result, report, seconds=time.perf_counter() - start)
    return result


def convert(inputs, out_dir, **kwargs) -> List[Dict[str, Any]]:
    """psq.convert on every input (see run() for the batch options, psq.convert for the rest)."""
    return run("convert", inputs, out_dir, **kwargs)


def simplify(inputs, out_dir, **kwargs) -> List[Dict[str, Any]]:
    """psq.simplify on every input (see run() for the batch options, psq.simplify for the rest)."""
    return run("simplify", inputs, out_dir, **kwargs)


def write_report(rows: List[Dict[str, Any]], path: Union[str, "os.PathLike[str]"],
                 seconds: Optional[float] = None) -> None:
    """Writes the rows as CSV (a .csv path) or JSON (anything else: {"files": rows, "summary": ...})."""
    path = os.fspath(path)
    if path.endswith(".csv"):
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(COLUMNS))
            w.writeheader()
            for r in rows:
                w.writerow({k: r.get(k) for k in COLUMNS})
        return
    summary = {"files": len(rows), "ok": sum(1 for r in rows if r["ok"]),
               "failed": sum(1 for r in rows if not r["ok"]),
               "bytes_in": sum(r["bytes_in"] or 0 for r in rows), "bytes_out": sum(r["bytes_out"] or 0 for r in rows)}
    if seconds is not None:
        summary["seconds"] = round(seconds, 6)
    with open(path, "w") as f:
        json.dump({"files": rows, "summary": summary}, f, indent=2)
        f.write("\n")


def _table(rows: List[Dict[str, Any]]) -> str:
    out = io.StringIO()
    out.write(f"{'status':<7} {'bytes in':>12} {'bytes out':>12} {'seconds':>9}  file\n")
    for r in rows:
        status = "ok" if r["ok"] else "FAILED"
        out.write(f"{status:<7} {r['bytes_in'] if r['bytes_in'] is not None else '-':>12} "
                  f"{r['bytes_out'] if r['bytes_out'] is not None else '-':>12} "
                  f"{r['seconds'] if r['seconds'] is not None else '-':>9}  {r['input']}")
        out.write(f" -> {r['output']}\n" if r["ok"] else f": {r['error']}\n")
    return out.getvalue()


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python3 -m psq.batch",
                                description="Convert or simplify many mesh files on Dask (a local cluster, or "
                                            "--scheduler). One row per file; exit status 1 if any failed.")
    sub = p.add_subparsers(dest="operation", required=True)
    for name in ("convert", "simplify"):
        s = sub.add_parser(name, help=f"psq {name} every input file")
        s.add_argument("inputs", nargs="+", help="a directory, a glob pattern (quoted) or files, then OUT_DIR")
        s.add_argument("--report", help="write the table to this file (.json or .csv)")
        s.add_argument("--scheduler", help="address of a running Dask scheduler (default: a local cluster)")
        s.add_argument("--workers", type=int, default=2, help="local cluster: worker processes (default 2)")
        s.add_argument("--to", default="psq", choices=("psq", "ply", "obj", "drc"), help="output format (default psq)")
        s.add_argument("--bits", type=int, help="quantization bits")
        s.add_argument("--lossless", action="store_true", help="keep positions bit-exact")
        s.add_argument("--profile", choices=("auto", "fast", "compact"), help=".psq profile")
        s.add_argument("--memory", help="memory budget per file (e.g. 256M)")
        s.add_argument("-f", "--force", action="store_true", help="overwrite existing outputs")
        s.add_argument("--json", action="store_true", help="print the rows as JSON instead of a table")
        if name == "simplify":
            s.add_argument("--method", choices=("clustering", "qem"), default="clustering")
            s.add_argument("--ratio", type=float, help="keep this fraction of the triangles")
            s.add_argument("--triangles", type=int, help="keep about this many triangles")
            s.add_argument("--grid", type=float, help="clustering: cells along the longest side")
            s.add_argument("--max-error", type=float, help="qem: largest error, relative to the diagonal")
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    """The command line; returns the exit status."""
    parser = _parser()
    try:
        a = parser.parse_args(argv)
    except SystemExit as e:
        return int(e.code or 0) and 2
    if len(a.inputs) < 2:
        parser.print_usage(sys.stderr)
        print("psq.batch: error: give the inputs and OUT_DIR", file=sys.stderr)
        return 2
    *inputs, out_dir = a.inputs
    if a.workers < 1:
        print("psq.batch: error: --workers must be at least 1", file=sys.stderr)
        return 2
    options: Dict[str, Any] = {"overwrite": a.force}
    for key in ("bits", "profile", "memory") + (("method", "ratio", "triangles", "grid", "max_error")
                                                  if a.operation == "simplify" else ()):
        v = getattr(a, key, None)
        if v is not None:
            options[key] = v
    if a.lossless:
        options["lossless"] = True
    if a.operation == "simplify" and options.get("method") == "qem" and not any(
            k in options for k in ("ratio", "triangles", "max_error")):
        print("psq.batch: error: simplify --method qem needs --ratio, --triangles or --max-error", file=sys.stderr)
        return 2
    files = expand_inputs(inputs[0] if len(inputs) == 1 else inputs)
    if not files:
        print(f"psq.batch: error: no input files in {' '.join(inputs)}", file=sys.stderr)
        return 2
    rows = run(a.operation, files, out_dir, scheduler=a.scheduler, workers=a.workers, to=a.to, report=a.report,
               **options)
    if a.json:
        json.dump(rows, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(_table(rows))
    failed = sum(1 for r in rows if not r["ok"])
    if failed:
        print(f"psq.batch: {failed} of {len(rows)} file(s) failed", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
