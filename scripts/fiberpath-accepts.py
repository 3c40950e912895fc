#!/usr/bin/env python3
"""FiberPath's own tools read windcell's Marlin programs.

    scripts/fiberpath-accepts.py --windcell PATH [--cache DIR] [--markdown OUT.md]

Installs FiberPath 0.11.0 from PyPI into the cache as scripts/fiberpath-compare.py does (the
same cache and sdist; nothing of FiberPath is copied into this repository), then for every `.wind`
of FiberPath's `examples/` and `conformance/valid/`:

  * `windcell lathe plan FILE --dialect marlin --json` (the default machine, `fiberpath-xab`),
  * checks that every X of the program lies within [0, windLength] and that it has no word
    but X, A, B and F,
  * `fiberpath simulate PROGRAM --json` and `fiberpath plot PROGRAM -o PNG` must both succeed,
  * compares simulate's time and tow with windcell's own summary.

Exit 0 when every file passes, 1 when one does not, 77 (skipped) when PyPI cannot be reached
and FiberPath is not in the cache yet. `cell/tests/fiberpath_tools.rs` runs it.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import importlib.util
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import urllib.request

SKIP = 77
HERE = pathlib.Path(__file__).resolve().parent


def compare_module():
    spec = importlib.util.spec_from_file_location("fiberpath_compare", HERE / "fiberpath-compare.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def pypi_reachable() -> bool:
    try:
        with urllib.request.urlopen("https://pypi.org/simple/fiberpath/", timeout=15) as r:
            return r.status == 200
    except OSError:
        return False


WORD = re.compile(r"^([A-Z])(-?[0-9.]+)$")


def check_words(text: str, wind_length: float) -> str | None:
    """None when every motion word is X, A, B or F and every X within [0, windLength]."""
    for n, line in enumerate(text.splitlines(), 1):
        if not line or line.startswith(";"):
            continue
        parts = line.split()
        if parts[0] not in ("G0", "G1", "G92", "G21", "G90", "G94"):
            return f"line {n}: code {parts[0]}"
        for w in parts[1:]:
            m = WORD.match(w)
            if not m or m.group(1) not in "XABF":
                return f"line {n}: word {w}"
            if m.group(1) == "X" and not (0.0 <= float(m.group(2)) <= wind_length + 1e-9):
                return f"line {n}: X {m.group(2)} outside [0, {wind_length}]"
    return None


def one(windcell: str, fiberpath: str, src: pathlib.Path, f: pathlib.Path, work: pathlib.Path):
    name = str(f.relative_to(src))
    wind = json.loads(f.read_text())
    out = work / re.sub(r"[^A-Za-z0-9]+", "_", name)
    plan = subprocess.run([windcell, "lathe", "plan", str(f), "-o", str(out), "--dialect",
                           "marlin", "--json"], capture_output=True, text=True)
    if plan.returncode != 0:
        return name, f"windcell lathe plan failed: {plan.stderr.strip()}", None
    summary = json.loads(plan.stdout)
    program = pathlib.Path(summary["file"])
    bad = check_words(program.read_text(), wind["mandrelParameters"]["windLength"])
    if bad:
        return name, bad, None
    sim = subprocess.run([fiberpath, "simulate", str(program), "--json"], capture_output=True,
                         text=True)
    if sim.returncode != 0:
        return name, f"fiberpath simulate refused: {(sim.stdout + sim.stderr).strip()}", None
    plot = subprocess.run([fiberpath, "plot", str(program), "-o", str(out / "plot.png")],
                          capture_output=True, text=True)
    if plot.returncode != 0 or not (out / "plot.png").stat().st_size:
        return name, f"fiberpath plot refused: {(plot.stdout + plot.stderr).strip()}", None
    s = json.loads(sim.stdout)
    return name, None, (summary, s)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--windcell", default=None)
    ap.add_argument("--cache", default=None)
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--setup-only", action="store_true",
                    help="install (or find) FiberPath, print its `fiberpath` path and stop")
    args = ap.parse_args()

    fc = compare_module()
    cache = fc.cache_dir(args.cache)
    try:
        py, src = fc.setup(cache)
    except (subprocess.CalledProcessError, OSError) as e:
        if not pypi_reachable():
            print(f"SKIPPED: PyPI (https://pypi.org) cannot be reached and FiberPath "
                  f"{fc.FIBERPATH} is not in {cache}: {e}", file=sys.stderr)
            return SKIP
        raise
    fiberpath = str(py.parent / "fiberpath")
    if args.setup_only:
        print(fiberpath)
        return 0
    files = sorted((src / "examples").rglob("*.wind")) + sorted(
        (src / "conformance" / "valid").glob("*.wind"))
    # windcell's own examples too.
    own = sorted((HERE.parent / "examples").glob("*.wind"))
    failures, rows = [], []
    with tempfile.TemporaryDirectory(prefix="fp-accepts-") as tmp:
        work = pathlib.Path(tmp)
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            results = list(pool.map(lambda f: one(args.windcell, fiberpath, src, f, work), files))
            results += list(pool.map(
                lambda f: one(args.windcell, fiberpath, HERE.parent, f, work), own))
    files += own
    for name, failure, figures in results:
        if failure:
            failures.append(f"{name}: {failure}")
            continue
        ours, sim = figures
        rows.append(
            f"| {name} | {sim['moves']} / {ours['moves']} "
            f"| {sim['tow_length_mm'] / 1000:.3f} / {ours['tow_length_mm'] / 1000:.3f} "
            f"| {sim['estimated_time_s']:.1f} / {ours['time_s']:.1f} "
            f"({ours['nominal_time_s']:.1f}) |")
    table = ("| File | moves: `fiberpath simulate` / windcell | tow m: simulate / windcell "
             "| time s: simulate / windcell (at the velocity limits alone) |\n"
             "|---|---|---|---|\n" + "\n".join(rows) + "\n")
    print(table)
    if args.markdown:
        pathlib.Path(args.markdown).write_text(table)
    print(f"{len(files)} files: {len(rows)} accepted by fiberpath simulate and plot, "
          f"{len(failures)} not")
    for f in failures:
        print("FAILED " + f, file=sys.stderr)
    return 1 if failures or not files else 0


if __name__ == "__main__":
    sys.exit(main())
