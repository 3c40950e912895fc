#!/usr/bin/env python3
"""Side-by-side: windcell's mesh tracer and commands against potpourri3d (geometry-central) and
trimesh, in one run (docs/benchmarks.md, "Mesh mandrels against potpourri3d").

    scripts/mesh-compare.py [--cache DIR] [--sizes 10000,80000,700000,2000000] [--skip-large]

It installs potpourri3d 1.4.0, trimesh and numpy from PyPI into a venv under the cache directory
(default $XDG_CACHE_HOME/windcell-mesh, else ~/.cache/windcell-mesh) and runs itself again inside
it. Then:

1. Per trace: `cargo bench -p paths --bench mesh_compare` writes a cylinder (r 30 mm, 400 mm,
   capped), a geodesic sphere (R 50 mm) and a torus (60/20 mm) at each size as binary STL with 32
   different paths each, traces them in windcell (smooth and exact mode, median of 5 rounds over
   the 32 paths) and writes its points. The same meshes (read with trimesh) and paths (start
   triangle's centroid, same direction and length) are traced by potpourri3d's GeodesicTracer,
   also the median of 5 rounds. Both are scored against the analytic geodesic from their points
   alone: the cylinder's helix (the unrolled path is straight), the sphere's great circle
   (distance from the plane of the start point, direction and centre), the torus's Clairaut
   constant r sin(angle to the meridian), each over the first 90 % of the length.
2. A 1 M-triangle binary STL (`windcell triasym examples/cylinder.toml`): `windcell geodesic`
   as a whole process against trimesh.load + potpourri3d.GeodesicTracer + the same trace timed
   inside Python (imports and interpreter start not counted for the peer).
3. The S-bend of `examples/sbend-mesh.toml` meshed at about 1 M triangles: `windcell plan` and
   `windcell check` as whole processes, wall time and peak resident memory (/usr/bin/time -v).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
POTPOURRI = "1.4.0"


def cache_dir(arg: str | None) -> pathlib.Path:
    if arg:
        return pathlib.Path(arg)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return pathlib.Path(base) / "windcell-mesh"


def venv_python(cache: pathlib.Path) -> pathlib.Path:
    venv = cache / f"venv-pp-{POTPOURRI}"
    py = venv / "bin" / "python"
    if not (venv / "ok").exists():
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "-q", f"potpourri3d=={POTPOURRI}",
                        "trimesh", "numpy"], check=True)
        (venv / "ok").write_text("ok\n")
    return py


def timed(cmd: list[str], cwd: pathlib.Path | None = None) -> tuple[float, int, str]:
    """Wall seconds, peak resident bytes (GNU time -v) and stdout of a whole process."""
    t0 = time.perf_counter()
    out = subprocess.run(["/usr/bin/time", "-v", *cmd], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({out.returncode}):\n{out.stderr[-2000:]}")
    peak = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", out.stderr).group(1))
    return wall, peak * 1024, out.stdout


# ---------------------------------------------------------------- accuracy, from points alone

def deviation(np, shape: str, pts, start, direction, length_mm: float) -> float:
    """Largest deviation from the analytic geodesic over the first 90 % of the path's length:
    mm for the cylinder and sphere, relative change of Clairaut's constant for the torus."""
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    keep = s <= 0.9 * min(length_mm, s[-1])
    p = pts[keep]
    if shape == "cylinder":
        theta = np.unwrap(np.arctan2(p[:, 1], p[:, 0]))
        u, z = 30.0 * theta, p[:, 2]
        # The helix through the start with the start direction, unrolled: a straight line.
        r0 = np.hypot(start[0], start[1])
        e_theta = np.array([-start[1], start[0], 0.0]) / r0
        du, dz = direction @ e_theta, direction[2]
        n = np.array([-dz, du]) / np.hypot(du, dz)
        return float(np.max(np.abs((u - u[0]) * n[0] + (z - z[0]) * n[1])))
    if shape == "icosphere":
        normal = np.cross(start, direction)
        normal /= np.linalg.norm(normal)
        return float(np.max(np.abs(p @ normal)))
    # Torus: r sin(angle between the path and the meridian) is constant (Clairaut).
    mid = 0.5 * (p[1:] + p[:-1])
    d = np.diff(p, axis=0)
    ok = np.linalg.norm(d, axis=1) > 1e-9
    mid, d = mid[ok], d[ok] / np.linalg.norm(d[ok], axis=1)[:, None]
    r = np.hypot(mid[:, 0], mid[:, 1])
    e_phi = np.stack([-mid[:, 1], mid[:, 0], np.zeros(len(mid))], axis=1) / r[:, None]
    c = r * np.einsum("ij,ij->i", d, e_phi)
    r0 = np.hypot(start[0], start[1])
    c0 = r0 * (direction @ np.array([-start[1], start[0], 0.0]) / r0)
    return float(np.max(np.abs(c - c0)) / 80.0)


# ---------------------------------------------------------------- the comparison, inside the venv

def per_trace(args, work: pathlib.Path) -> list[dict]:
    import numpy as np
    import potpourri3d as pp3d
    import trimesh

    data = work / "traces"
    subprocess.run(["cargo", "bench", "-p", "paths", "--bench", "mesh_compare", "--",
                    str(data), args.sizes], cwd=ROOT, check=True)
    meshes = json.loads((data / "windcell.json").read_text())
    rows = []
    for m in meshes:
        name, shape = m["name"], m["shape"]
        paths = json.loads((data / f"{name}.json").read_text())
        mesh = trimesh.load(str(data / f"{name}.stl"), process=True)
        assert len(mesh.faces) == m["triangles"], (len(mesh.faces), m["triangles"])
        V = np.asarray(mesh.vertices, dtype=np.float64)
        F = np.asarray(mesh.faces, dtype=np.int64)
        t0 = time.perf_counter()
        tracer = pp3d.GeodesicTracer(V, F)
        build = time.perf_counter() - t0
        third = np.array([1.0, 1.0, 1.0]) / 3.0

        def trace(p):
            return tracer.trace_geodesic_from_face(p["face"], third,
                                                   np.array(p["direction"]) * p["length_mm"])

        theirs = [np.asarray(trace(p)) for p in paths]
        rounds = []
        for _ in range(5):
            t0 = time.perf_counter()
            for p in paths:
                trace(p)
            rounds.append(time.perf_counter() - t0)
        pp_per_trace = sorted(rounds)[2] / len(paths)
        flat = np.fromfile(data / f"{name}.f64", dtype="<f8").reshape(-1, 3)
        ours, at = [], 0
        for p in paths:
            ours.append(flat[at:at + p["points"]])
            at += p["points"]
        dev = lambda pts, p: deviation(np, shape, pts, np.array(p["point"]),
                                       np.array(p["direction"]), p["length_mm"])
        wc_dev = max(dev(o, p) for o, p in zip(ours, paths))
        pp_dev = max(dev(t, p) for t, p in zip(theirs, paths))
        row = {
            "mesh": name, "shape": shape, "triangles": m["triangles"],
            "windcell_smooth_s": m["smooth"]["per_trace_s"],
            "windcell_exact_s": m["exact"]["per_trace_s"],
            "potpourri3d_s": pp_per_trace,
            "ratio_smooth": m["smooth"]["per_trace_s"] / pp_per_trace,
            "crossings_per_trace": m["smooth"]["crossings"] / len(paths),
            "smooth_mcps": m["smooth"]["crossings_per_s"] / 1e6,
            "smooth_warm_mcps": m["smooth"]["warm_crossings_per_s"] / 1e6,
            "exact_mcps": m["exact"]["crossings_per_s"] / 1e6,
            "windcell_prepare_s": m["prepare_s"], "potpourri3d_build_s": build,
            "windcell_deviation": wc_dev, "potpourri3d_deviation": pp_dev,
        }
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def windcell_bin() -> pathlib.Path:
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "cell", "--bin", "windcell"],
                   cwd=ROOT, check=True)
    return ROOT / "target" / "release" / "windcell"


def whole_process(work: pathlib.Path, windcell: pathlib.Path) -> dict:
    import numpy as np
    import potpourri3d as pp3d
    import trimesh

    stl = work / "cylinder-1m.stl"
    # examples/cylinder.toml meshed at 1024 facets with 0.37 mm sections: about 1 M triangles.
    subprocess.run([str(windcell), "triasym", str(ROOT / "examples" / "cylinder.toml"), "-o",
                    str(stl), "--facets", "1024", "--spacing-mm", "0.37"], check=True,
                   capture_output=True)
    start = "31.75,0,60"
    wall, peak, out = timed([str(windcell), "geodesic", str(stl), "--start", start, "--heading",
                             "45", "--length", "600", "--json"])
    ours = json.loads(out)
    t0 = time.perf_counter()
    mesh = trimesh.load(str(stl), process=True)
    t1 = time.perf_counter()
    V = np.asarray(mesh.vertices, dtype=np.float64)
    F = np.asarray(mesh.faces, dtype=np.int64)
    tracer = pp3d.GeodesicTracer(V, F)
    t2 = time.perf_counter()
    p0 = np.array([31.75, 0.0, 60.0])
    vertex = int(np.argmin(np.linalg.norm(V - p0, axis=1)))
    direction = np.array([0.0, np.sin(np.radians(45)), np.cos(np.radians(45))]) * 600.0
    theirs = tracer.trace_geodesic_from_vertex(vertex, direction)
    t3 = time.perf_counter()
    row = {
        "triangles": len(mesh.faces), "stl_bytes": stl.stat().st_size,
        "windcell_geodesic_s": wall, "windcell_peak_bytes": peak,
        "windcell_crossings": ours["crossings"],
        "trimesh_load_s": t1 - t0, "potpourri3d_build_s": t2 - t1, "potpourri3d_trace_s": t3 - t2,
        "peer_total_s": t3 - t0, "peer_points": len(theirs),
    }
    row["ratio"] = wall / row["peer_total_s"]
    print(json.dumps(row), flush=True)
    return row


def sbend(work: pathlib.Path, windcell: pathlib.Path) -> dict:
    job = (ROOT / "examples" / "sbend-mesh.toml").read_text()
    stl = work / "sbend-1m.stl"
    # 1024 facets with 0.72 mm sections: about 1 M triangles on the S-bend.
    made = subprocess.run([str(windcell), "triasym", str(ROOT / "examples" / "sbend-mesh.toml"),
                           "-o", str(stl), "--facets", "1024", "--spacing-mm", "0.72"],
                          check=True, capture_output=True, text=True).stdout
    triangles = int(re.search(r"\((\d+) triangles\)", made).group(1))
    (work / "sbend-1m.toml").write_text(job.replace('mesh = "sbend.stl"', 'mesh = "sbend-1m.stl"'))
    row = {"triangles": triangles}
    for name, cmd in [("plan", ["plan", str(work / "sbend-1m.toml"), "-o", str(work / "plan")]),
                      ("check", ["check", str(work / "sbend-1m.toml")])]:
        runs = [timed([str(windcell), *cmd]) for _ in range(3)]
        row[f"{name}_s"] = sorted(r[0] for r in runs)[1]
        row[f"{name}_peak_bytes"] = max(r[1] for r in runs)
        row[f"{name}_bytes_per_triangle"] = row[f"{name}_peak_bytes"] / triangles
    print(json.dumps(row), flush=True)
    return row


def inner(args) -> None:
    work = cache_dir(args.cache) / "work"
    work.mkdir(parents=True, exist_ok=True)
    report = {"per_trace": per_trace(args, work)}
    if not args.skip_large:
        windcell = windcell_bin()
        report["geodesic_1m"] = whole_process(work, windcell)
        report["sbend_1m"] = sbend(work, windcell)
    (work / "report.json").write_text(json.dumps(report, indent=1))
    print("\n| mesh | triangles | windcell smooth per trace | potpourri3d per trace | ratio | "
          "crossings/s over 32 paths (warm) | exact mode | deviation windcell / potpourri3d |")
    print("|---|---|---|---|---|---|---|---|")
    for r in report["per_trace"]:
        unit = "" if r["shape"] == "torus" else " mm"
        print(f"| {r['shape']} | {r['triangles']} | {r['windcell_smooth_s'] * 1e3:.3f} ms | "
              f"{r['potpourri3d_s'] * 1e3:.3f} ms | {r['ratio_smooth']:.2f} | "
              f"{r['smooth_mcps']:.1f} M ({r['smooth_warm_mcps']:.1f} M) | {r['exact_mcps']:.1f} M | "
              f"{r['windcell_deviation']:.2e}{unit} / {r['potpourri3d_deviation']:.2e}{unit} |")
    print(f"\nreport: {work / 'report.json'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache")
    ap.add_argument("--sizes", default="10000,80000,700000,2000000")
    ap.add_argument("--skip-large", action="store_true",
                    help="only the per-trace comparison")
    ap.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.inner:
        inner(args)
        return
    py = venv_python(cache_dir(args.cache))
    cmd = [str(py), __file__, "--inner", "--sizes", args.sizes, "--cache",
           str(cache_dir(args.cache))]
    if args.skip_large:
        cmd.append("--skip-large")
    sys.exit(subprocess.run(cmd).returncode)


if __name__ == "__main__":
    main()
