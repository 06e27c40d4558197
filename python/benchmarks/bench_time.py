#!/usr/bin/env python3
"""Many time steps at fixed points: tetloc's weights (locate once, ``W @ f`` per step) against
scipy's LinearNDInterpolator (its Delaunay built once on the mesh's points, evaluated per
step), VTK's vtkProbeFilter once per step, and tetloc's own ``sample`` once per step.

The field changes in time as the time data's README rule, f_t = f (1 + 0.25 t) + t (f: the
mesh's vertex field ``f``, or x + 2y + 3z), computed in memory for every step (no file is
read: the same cost for every peer, and small next to the interpolation). The slow peers run
``--sample-steps`` steps and are scaled to all of them (the table says so). Prints seconds
for the whole job and the ratios.

  python python/benchmarks/bench_time.py --fusion 1.4M --points 1M --steps 1000 [--json FILE]
  python python/benchmarks/bench_time.py --mesh FILE.vtu ...

``--fusion`` needs the ``tetloc`` CLI (``TETLOC_CLI`` or target/release/tetloc) to generate
the mesh; measure with a release wheel.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import tempfile
import time

import numpy as np

import tetloc

REPO = pathlib.Path(__file__).resolve().parents[2]


def mesh_file(args) -> pathlib.Path:
    if args.mesh:
        return pathlib.Path(args.mesh)
    cli = os.environ.get("TETLOC_CLI") or str(REPO / "target/release/tetloc")
    path = pathlib.Path(tempfile.gettempdir()) / f"bench_time_fusion_{args.fusion}.vtu"
    if not path.exists():
        subprocess.run([cli, "gen", "fusion", "--tets", args.fusion, "-o", str(path)], check=True)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh")
    ap.add_argument("--fusion", default="1.4M")
    ap.add_argument("--points", type=float, default=1e6)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--sample-steps", type=int, default=3, help="steps the slow peers run (scaled up)")
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--json")
    args = ap.parse_args()

    path = mesh_file(args)
    mesh = tetloc.read(path)
    verts = mesh.points64
    base = mesh.field("f").astype(np.float64) if "f" in mesh.point_data else verts @ [1.0, 2.0, 3.0]
    lo, hi = np.reshape(mesh.bounds, (3, 2)).T
    pts = np.random.default_rng(1).uniform(lo, hi, size=(int(args.points), 3))
    times = np.linspace(0.0, 2.5, args.steps)
    step = lambda t: base * (1 + 0.25 * t) + t  # noqa: E731
    rows = {}

    t0 = time.perf_counter()
    loc = tetloc.Locator(mesh, backend=args.backend)
    W = loc.weights(pts)
    t_locate = time.perf_counter() - t0
    out = np.empty(len(pts))
    t0 = time.perf_counter()
    for t in times:
        out[:] = W @ step(t)
    rows["tetloc weights"] = (t_locate + time.perf_counter() - t0, args.steps, f"locate once {t_locate:.2f} s")
    check = out.copy()

    t0 = time.perf_counter()
    for _ in range(args.sample_steps):
        loc.sample(pts, "f") if "f" in mesh.point_data else loc.locate(pts)
    per = (time.perf_counter() - t0) / args.sample_steps
    rows["tetloc sample per step"] = (per * args.steps, args.sample_steps, "scaled")

    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import Delaunay

    t0 = time.perf_counter()
    tri = Delaunay(verts)
    t_tri = time.perf_counter() - t0
    t0 = time.perf_counter()
    for t in times[-args.sample_steps:]:
        got = LinearNDInterpolator(tri, step(t))(pts)
    per = (time.perf_counter() - t0) / args.sample_steps
    rows["scipy LinearNDInterpolator"] = (t_tri + per * args.steps, args.sample_steps, f"Delaunay {t_tri:.2f} s, scaled")
    inside = ~np.isnan(got)
    print(f"scipy vs tetloc at the last step: max |diff| {np.nanmax(np.abs(got[inside] - check[inside])):.3g} "
          "(scipy interpolates in its own Delaunay tets, not the mesh's)")

    import pyvista as pv
    import vtk

    grid = mesh.to_pyvista()
    probe_pts = pv.PolyData(pts)
    t0 = time.perf_counter()
    for t in times[-args.sample_steps:]:
        grid.point_data["f_t"] = step(t)
        p = vtk.vtkProbeFilter()
        p.SetInputData(probe_pts)
        p.SetSourceData(grid)
        p.Update()
    per = (time.perf_counter() - t0) / args.sample_steps
    rows["VTK vtkProbeFilter per step"] = (per * args.steps, args.sample_steps, "scaled")

    ours = rows["tetloc weights"][0]
    print(f"{path.name}: {mesh.n_cells} cells, {len(pts)} points, {args.steps} steps, backend {loc.backend}")
    for name, (sec, ran, note) in rows.items():
        print(f"  {name:32s} {sec:10.2f} s  ({ran} steps run; {note})  tetloc weights is {sec / ours:6.1f}x faster")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({k: v[0] for k, v in rows.items()}, indent=1))


if __name__ == "__main__":
    main()
