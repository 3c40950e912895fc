#!/usr/bin/env python3
"""windcell lathe plan side by side with FiberPath 0.11 on FiberPath's own .wind files.

Run by hand (not in CI); results are recorded in docs/fiberpath.md:

    scripts/fiberpath-compare.py [--windcell PATH] [--cache DIR] [--markdown OUT.md]

It installs FiberPath 0.11.0 from PyPI into a venv under the cache directory (default
$XDG_CACHE_HOME/windcell-fiberpath, else ~/.cache/windcell-fiberpath), downloads and unpacks its
sdist there for the example and conformance files, and plans every `.wind` of `examples/` and
`conformance/valid/` with both `fiberpath plan` and `windcell lathe plan --dialect marlin`.
Nothing of FiberPath is copied into this repository; the files are read where they were unpacked.

Compared, from the two G-code files (the same reading for both, independent of either planner):
  * circuits per layer (FiberPath: its `Circuit:` comments; windcell: the summary),
  * the wind angle of every pass, from the pass's mandrel turn and carriage travel: on a cylinder
    tan α = r·Δθ/L; on a cone the large-end angle whose geodesic turns by Δθ, found by bisection
    on r·dθ = tan α·ds integrated numerically (Clairaut, sin α = r0·sin α0 / r); on a von Kármán
    nose the angle at the base whose path (the geodesic, or with the layer's frictionLambda λ the
    path with k_g = −λ·k_n) turns by Δθ over the pass's travel, by bisection on the path
    integrated with RK4 (see `Mandrel.nose_turn_deg`),
  * tow length: each planner's own total, and both programs measured the same way on the real
    surface, split into the passes (carriage moving) and the end turns (carriage still),
  * planning time: `fiberpath plan` and `windcell lathe plan` wall time (best of --repeat runs),
    and FiberPath's `plan_wind` alone, in process (without interpreter start-up or file output).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time

FIBERPATH = "0.11.0"


def cache_dir(arg: str | None) -> pathlib.Path:
    if arg:
        return pathlib.Path(arg)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return pathlib.Path(base) / "windcell-fiberpath"


def setup(cache: pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
    """Returns (venv python, unpacked sdist)."""
    cache.mkdir(parents=True, exist_ok=True)
    venv = cache / f"venv-{FIBERPATH}"
    py = venv / "bin" / "python"
    if not (venv / "bin" / "fiberpath").exists():
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "-q", f"fiberpath=={FIBERPATH}"], check=True)
    src = cache / f"fiberpath-{FIBERPATH}"
    if not src.exists():
        dl = cache / "sdist"
        subprocess.run(
            [str(py), "-m", "pip", "download", "-q", f"fiberpath=={FIBERPATH}", "--no-deps",
             "--no-binary", ":all:", "-d", str(dl)],
            check=True,
        )
        with tarfile.open(dl / f"fiberpath-{FIBERPATH}.tar.gz") as t:
            t.extractall(cache, filter="data")
    return py, src


class Mandrel:
    def __init__(self, wind: dict):
        m = wind["mandrelParameters"]
        self.r0 = m["diameter"] / 2.0
        self.r1 = m.get("endDiameter", m["diameter"]) / 2.0
        self.length = m["windLength"]
        self.cos_phi = self.length / math.hypot(self.r0 - self.r1, self.length)
        self.profile = m.get("profile")
        self._cache = {}

    # The von Kármán nose (Haack series, C = 0), parametrised by u = π − φ from the base:
    # z = L(1 − cos u)/2, r = R·√(F/π) with F = π − u + sin 2u / 2.
    def _vk(self, u: float):
        f = max(math.pi - u + math.sin(2 * u) / 2, 0.0)
        k = 2 * self.r0 / (self.length * math.sqrt(math.pi))
        s, c = math.sin(u), math.cos(u)
        return (self.length * (1 - c) / 2, self.length * s / 2, self.r0 * math.sqrt(f / math.pi),
                -k * s / math.sqrt(f), -k * (c / math.sqrt(f) + s ** 3 / f ** 1.5))

    def _u_at(self, z: float) -> float:
        return math.acos(max(-1.0, min(1.0, 1 - 2 * z / self.length)))

    def radius(self, z: float) -> float:
        if self.profile:
            return self._vk(self._u_at(z))[2]
        return self.r0 - (self.r0 - self.r1) * z / self.length

    def meridian(self, z0: float, z1: float) -> float:
        """Meridian length between two axial positions (short: the slope at the middle)."""
        if self.profile:
            slope = self._vk(self._u_at(0.5 * (z0 + z1)))[3]
            return abs(z1 - z0) * math.sqrt(1 + slope * slope)
        return abs(z1 - z0) / self.cos_phi

    def nose_turn_deg(self, alpha0_deg: float, travel: float, lam: float):
        """Mandrel turn of the nose path leaving the base at α0, up to `travel` from the base, or
        None if it turns around (α = 90°) before. The path: dα/ds = −sin α·(dr/dm)/r − λ·k_n,
        k_n = k_m·cos²α + k_p·sin²α, integrated in τ (ds = dm/du·dτ) by RK4."""
        def rate(y):
            u, a = y[0], y[1]
            _, zu, r, sl, slu = self._vk(u)
            w2 = 1 + sl * sl
            mu = zu * math.sqrt(w2)
            sa, ca = math.sin(a), math.cos(a)
            return (ca, -sa * sl * zu / r - lam * (-slu * ca * ca / w2 + zu * sa * sa / r),
                    mu * sa / r)

        def step(y, h):
            k1 = rate(y)
            k2 = rate([y[i] + h / 2 * k1[i] for i in range(3)])
            k3 = rate([y[i] + h / 2 * k2[i] for i in range(3)])
            k4 = rate([y[i] + h * k3[i] for i in range(3)])
            return [y[i] + h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]) for i in range(3)]

        target = self._u_at(travel)
        y = [0.0, math.radians(alpha0_deg), 0.0]
        while True:
            _, zu, r, sl, _ = self._vk(y[0])
            mu = zu * math.sqrt(1 + sl * sl)
            h = min(r / 100 / mu if mu > 0 else math.inf, 4e-3 / max(abs(math.cos(y[1])), 1e-9))
            nxt = step(y, h)
            if nxt[1] >= math.pi / 2 and nxt[0] < target:
                return None
            if nxt[0] >= target:
                # Land on the target by Newton on the step (du/dτ = cos α).
                for _ in range(30):
                    miss = nxt[0] - target
                    if abs(miss) < 1e-13:
                        break
                    h -= miss / math.cos(nxt[1])
                    nxt = step(y, h)
                if nxt[1] > math.pi / 2:
                    return None
                return math.degrees(nxt[2])
            y = nxt

    def pass_turn_deg(self, alpha0_deg: float) -> float:
        """Mandrel turn over a whole pass (Simpson, 2000 intervals) at α0 at the large end."""
        if self.r0 == self.r1:
            return math.degrees(self.length * math.tan(math.radians(alpha0_deg)) / self.r0)
        c = self.r0 * math.sin(math.radians(alpha0_deg))
        n = 2000
        h = self.length / n
        total = 0.0
        for i in range(n + 1):
            r = self.radius(i * h)
            s = min(c / r, 1.0 - 1e-15)
            f = s / math.sqrt(1.0 - s * s) / (r * self.cos_phi)
            total += f * (1 if i in (0, n) else 4 if i % 2 else 2)
        return math.degrees(total * h / 3.0)

    def nose_angle_deg(self, travel: float, turn_deg: float, lam: float) -> float:
        key = (round(travel, 9), round(turn_deg, 9), lam)
        if key not in self._cache:
            lo, hi = 1e-3, 89.999
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                t = self.nose_turn_deg(mid, travel, lam)
                if t is None or t > turn_deg:
                    hi = mid
                else:
                    lo = mid
            self._cache[key] = 0.5 * (lo + hi)
        return self._cache[key]

    def pass_angle_deg(self, turn_deg: float) -> float:
        if self.r0 == self.r1:
            return math.degrees(math.atan(self.r0 * math.radians(turn_deg) / self.length))
        lo, hi = 1e-6, math.degrees(math.asin(self.r1 / self.r0)) - 1e-6
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if self.pass_turn_deg(mid) < turn_deg:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)


WORD = re.compile(r"([A-Z])(-?[0-9.]+)")


def read_gcode(path: pathlib.Path, carriage_offset: float, layer_re: str, circuit_re: str | None,
               rapids_lay: bool):
    """Layers of a G-code file: each a list of (z0, a0, z1, a1) moves (z from the large end, a
    continuous through G92) and its circuit-comment count. FiberPath writes every move as G0;
    windcell writes G0 only for the rapid to the first layer's start, before the tow is tied on,
    so with `rapids_lay` False a G0 moves the axes without laying tow."""
    layers = []
    pos = {"X": 0.0, "A": 0.0}
    a_offset = 0.0
    for line in path.read_text().splitlines():
        if line.startswith(";"):
            if re.search(layer_re, line):
                layers.append({"moves": [], "circuits": 0})
            elif circuit_re and re.search(circuit_re, line) and layers:
                layers[-1]["circuits"] += 1
            continue
        code = line.split(";")[0].strip()
        words = dict(WORD.findall(code))
        if code.startswith("G92"):
            if "A" in words:
                a_offset += pos["A"] - float(words["A"])
                pos["A"] = float(words["A"])
            continue
        if not (code.startswith("G0") or code.startswith("G1")):
            continue
        new = dict(pos)
        for k in ("X", "A"):
            if k in words:
                new[k] = float(words[k])
        lays = rapids_lay or not code.startswith("G0")
        if layers and lays and (new["X"] != pos["X"] or new["A"] != pos["A"]):
            layers[-1]["moves"].append(
                (pos["X"] - carriage_offset, pos["A"] + a_offset,
                 new["X"] - carriage_offset, new["A"] + a_offset)
            )
        pos = new
    return layers


def measure(layer_moves, mandrel: Mandrel):
    """Passes (runs of carriage moves one way) as (travel, turn), pass tow and end-turn tow."""
    passes, pass_tow, turn_tow = [], 0.0, 0.0
    run = None
    for z0, a0, z1, a1 in layer_moves:
        if z1 != z0:
            zm = 0.5 * (z0 + z1)
            pass_tow += math.hypot(mandrel.meridian(z0, z1),
                                   mandrel.radius(zm) * math.radians(a1 - a0))
            way = math.copysign(1.0, z1 - z0)
            if run and run[2] != way:
                passes.append((run[0], run[1]))
                run = None
            run = run or [0.0, 0.0, way]
            run[0] += abs(z1 - z0)
            run[1] += abs(a1 - a0)
        else:
            turn_tow += mandrel.radius(z0) * abs(math.radians(a1 - a0))
            if run:
                passes.append((run[0], run[1]))
                run = None
    if run:
        passes.append((run[0], run[1]))
    return passes, pass_tow, turn_tow


def timed(cmd, repeat: int):
    best, out = math.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = subprocess.run(cmd, capture_output=True, text=True)
        best = min(best, time.perf_counter() - t)
    return best, out


IN_PROCESS = """
import sys, time
from fiberpath.config import load_wind_definition
from fiberpath.planning import PlanOptions, plan_wind
d = load_wind_definition(sys.argv[1])
best = min(
    (lambda t: (plan_wind(d, PlanOptions()), time.perf_counter() - t)[1])(time.perf_counter())
    for _ in range(int(sys.argv[2]))
)
print(best)
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--windcell", default=None, help="windcell binary (default: build with cargo)")
    ap.add_argument("--cache", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--markdown", default=None, help="also write the tables to this file")
    ap.add_argument("--invalid-only", action="store_true",
                    help="only the refusals of conformance/invalid (a few seconds)")
    args = ap.parse_args()

    repo = pathlib.Path(__file__).resolve().parent.parent
    windcell = args.windcell
    if windcell is None:
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "cell"], cwd=repo, check=True)
        target = os.environ.get("CARGO_TARGET_DIR", str(repo / "target"))
        windcell = str(pathlib.Path(target) / "release" / "windcell")
    py, src = setup(cache_dir(args.cache))
    fiberpath = str(py.parent / "fiberpath")
    files = sorted((src / "examples").rglob("*.wind")) + sorted(
        (src / "conformance" / "valid").glob("*.wind"))
    if args.invalid_only:
        files = []

    rows, times, notes = [], [], []
    work = pathlib.Path(tempfile.mkdtemp(prefix="fp-compare-"))
    for f in files:
        name = str(f.relative_to(src))
        wind = json.loads(f.read_text())
        mandrel = Mandrel(wind)
        fp_out = work / "fp.gcode"
        ours_dir = work / "ours"
        shutil.rmtree(ours_dir, ignore_errors=True)
        fp_t, fp = timed([fiberpath, "plan", str(f), "-o", str(fp_out), "--json"], args.repeat)
        our_t, ours = timed(
            [windcell, "lathe", "plan", str(f), "-o", str(ours_dir), "--dialect", "marlin", "--force",
             "--json"], max(args.repeat, 5))
        if fp.returncode != 0:
            rows.append((name, "FiberPath refused", "", "", "", "", ""))
            continue
        if ours.returncode != 0:
            reason = ours.stderr.strip().replace(str(f), f.name).split(": ", 1)[-1]
            fp_json = json.loads(fp.stdout)
            rows.append((name, f"windcell refuses: {reason}", "", "", "",
                         f"{fp_json['towMeters']:.3f} / –", ""))
            continue
        fp_json = json.loads(fp.stdout)
        our_json = json.loads(ours.stdout)
        fp_layers = read_gcode(fp_out, 0.0, r"^; Layer \d+ of", r"Circuit:", True)
        our_layers = read_gcode(pathlib.Path(our_json["file"]), 0.0,
                                r"^; layer \d+ ", None, False)
        inproc = subprocess.run([str(py), "-c", IN_PROCESS, str(f), str(args.repeat)],
                                capture_output=True, text=True, check=True)
        fp_plan_t = float(inproc.stdout.strip())
        times.append((name, fp_t, fp_plan_t, our_t, fp_json["commands"], our_json["lines"]))
        if len(fp_layers) != len(our_layers):
            rows.append((name, f"layers {len(fp_layers)} vs {len(our_layers)}", "", "", "", "", ""))
            continue
        for i, (fl, ol) in enumerate(zip(fp_layers, our_layers)):
            kind = wind["layers"][i]["windType"]
            ours_mark = our_json["layer"][i]
            fp_pass, fp_ptow, fp_ttow = measure(fl["moves"], mandrel)
            our_pass, our_ptow, our_ttow = measure(ol["moves"], mandrel)
            circuits = f"{fl['circuits']} / {ours_mark['circuits']}" if kind == "helical" else "–"
            if mandrel.profile:
                # A nose pass runs from the base to its turnaround: every pass longer than the
                # lead-in, its angle at the base from its travel and turn.
                lam = wind["layers"][i].get("frictionLambda", 0.0)
                lead = wind["layers"][i].get("leadInMM", 0.0)
                full = lambda ps: [p for p in ps if p[0] > lead]
                angle_of = lambda p: mandrel.nose_angle_deg(p[0], p[1], lam)
            else:
                full = lambda ps: [p for p in ps if abs(p[0] - mandrel.length) < 1e-6]
                angle_of = lambda p: mandrel.pass_angle_deg(p[1])
            fa = [angle_of(p) for p in full(fp_pass)] if kind != "skip" else []
            oa = [angle_of(p) for p in full(our_pass)] if kind != "skip" else []
            if fa and oa and len(fa) == len(oa):
                worst = max(abs(a - b) for a, b in zip(fa, oa))
                angle = f"{min(fa):.3f}–{max(fa):.3f} / {min(oa):.3f}–{max(oa):.3f} (Δ ≤ {worst:.4f})"
            elif fa or oa:
                angle = (f"{len(fa)} passes {min(fa, default=0):.3f} / "
                         f"{len(oa)} passes {min(oa, default=0):.3f}")
            else:
                angle = "–"
            fp_tow = fp_json["layers"][i]["tow_m"]
            our_tow = ours_mark["tow_length_mm"] / 1000.0
            pass_d = (our_ptow - fp_ptow) / fp_ptow * 100 if fp_ptow else 0.0
            rows.append((
                f"{name} L{i + 1} {kind}",
                circuits,
                f"{len(fp_pass)} / {len(our_pass)}",
                angle,
                f"{fp_ptow / 1000:.3f} / {our_ptow / 1000:.3f} ({pass_d:+.2f} %)",
                f"{fp_tow:.3f} / {our_tow:.3f}",
                f"{fp_ttow / 1000:.3f} / {our_ttow / 1000:.3f}",
            ))
    shutil.rmtree(work, ignore_errors=True)

    head = ("| File, layer | Circuits FP / ours | Passes FP / ours | Pass wind angle ° FP / ours "
            "| Pass tow m (same measure) | Tow m, each planner's own | End-turn tow m (same measure) |\n"
            "|---|---|---|---|---|---|---|\n")
    table = head + "".join("| " + " | ".join(r) + " |\n" for r in rows)
    thead = ("\n| File | `fiberpath plan` s | FiberPath `plan_wind` s | `windcell lathe plan` s "
             "| ratio (CLI) | ratio (plan_wind / our CLI) | lines FP / ours |\n"
             "|---|---|---|---|---|---|---|\n")
    ttable = thead + "".join(
        f"| {n} | {a:.3f} | {b:.3f} | {c:.4f} | {a / c:.0f}× | {b / c:.0f}× | {lf} / {lo} |\n"
        for n, a, b, c, lf, lo in times)
    largest = max(times, key=lambda t: t[2]) if times else None
    summary = ""
    if largest:
        summary = (f"\nLargest example by FiberPath planning time: {largest[0]}: "
                   f"{largest[1] / largest[3]:.0f}× (CLI) and {largest[2] / largest[3]:.0f}× "
                   f"(FiberPath's plan_wind alone against our whole CLI run).\n")
    # FiberPath's invalid corpus: both must refuse; windcell with exit 2 and one located line.
    refusals = ("\n| conformance/invalid | FiberPath exit | windcell exit | windcell's message |\n"
                "|---|---|---|---|\n")
    with tempfile.TemporaryDirectory() as out:
        for f in sorted((src / "conformance" / "invalid").glob("*.wind")):
            fp = subprocess.run([fiberpath, "plan", str(f), "-o", f"{out}/fp.gcode"],
                                capture_output=True, text=True)
            ours = subprocess.run([windcell, "lathe", "plan", str(f), "-o", f"{out}/ours",
                                   "--dialect", "marlin", "--force"], capture_output=True, text=True)
            message = ours.stderr.strip().replace(str(f), f.name).replace("|", "\\|")
            refusals += f"| {f.name} | {fp.returncode} | {ours.returncode} | {message} |\n"
    text = (table + ttable + summary if rows else "") + refusals
    print(text)
    if args.markdown:
        pathlib.Path(args.markdown).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
