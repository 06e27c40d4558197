#!/usr/bin/env python3
"""tetloc's resample, probe and trace against VTK's filters, same machine, same run.

On one mesh (by default ``torus_s.vtu`` of the oracle data, or ``--mesh FILE``, or ``--fusion
1.4M`` for the shape `tetloc gen fusion` writes) with a swirl vector field added,
v = (-y + 0.2 x, x + 0.2 y, 0.3) over the mesh's centred coordinates:

  - ``tetloc.resample_to_image`` of every field onto an N^3 grid vs ``vtkResampleToImage``;
  - ``tetloc.probe`` at K random points of the bounding box vs ``vtkResampleWithDataSet``;
  - ``tetloc.trace`` (RK4, a fixed step of a tenth of the mean edge) from S seeds for at most
    M steps vs ``vtkStreamTracer`` with the same integrator, step and limits;

each with the locator build included (VTK builds its own), the best of ``--repeats`` runs for
tetloc, one run for VTK; printing seconds, points (or steps) per second and the ratio.

Run it from the repository root:  python python/benchmarks/bench_ops.py [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import time
from typing import Callable, Dict, List

import numpy as np

import tetloc

REPO = pathlib.Path(__file__).resolve().parents[2]


def timed(f: Callable[[], object], repeats: int = 1):
    """(best seconds over `repeats`, the last result)."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def swirl(points: np.ndarray, centre: np.ndarray, scale: float) -> np.ndarray:
    x, y, _ = ((points - centre) / scale).T
    return np.stack([-y + 0.2 * x, x + 0.2 * y, np.full_like(x, 0.3)], axis=1).astype(np.float32)


def vtk_points(p: np.ndarray):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk

    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(p, dtype=np.float32), deep=True))
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    return poly


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mesh", help="a mesh file (default: torus_s.vtu of TETLOC_DATA or ../shared/data)")
    ap.add_argument("--fusion", help="generate the fusion shape of this many tets instead (e.g. 1.4M)")
    ap.add_argument("--dims", type=int, default=128, help="resample grid points per axis (default 128)")
    ap.add_argument("--probe-points", type=int, default=1_000_000, help="probe points (default 1M)")
    ap.add_argument("--seeds", type=int, default=1000, help="streamline seeds (default 1000)")
    ap.add_argument("--max-steps", type=int, default=1000, help="steps per streamline (default 1000)")
    ap.add_argument("--backend", default="cpu", help="tetloc's backend (default cpu)")
    ap.add_argument("--repeats", type=int, default=3, help="tetloc runs, best taken (default 3)")
    ap.add_argument("--json", help="also write the results here")
    a = ap.parse_args()

    import pyvista as pv
    import vtk

    if a.fusion:
        path = pathlib.Path(os.environ.get("TMPDIR", "/tmp")) / f"tetloc-bench-fusion-{a.fusion}.vtu"
        if not path.exists():
            cli = next((str(p) for p in (REPO / "target/release/tetloc", REPO / "target/debug/tetloc") if p.is_file()))
            subprocess.run([cli, "gen", "fusion", "--tets", a.fusion, "-o", str(path), "--quiet"], check=True)
    elif a.mesh:
        path = pathlib.Path(a.mesh)
    else:
        data = pathlib.Path(os.environ.get("TETLOC_DATA") or REPO.parent / "shared" / "data")
        path = data / "torus_s.vtu"
    grid = pv.read(path)
    lo, hi = np.asarray(grid.bounds).reshape(3, 2).T
    grid.point_data["v"] = swirl(np.asarray(grid.points), (lo + hi) / 2, float(np.max(hi - lo)) / 2)
    grid.point_data.active_vectors_name = "v"
    mesh = tetloc.Mesh.from_pyvista(grid)
    print(f"{path.name}: {mesh.n_cells} tets, {mesh.n_points} points; fields {list(mesh.point_data)}", file=sys.stderr)
    step = 0.1 * mesh.info()["mesh"]["mean_edge_length"]
    rng = np.random.default_rng(1)
    rows: List[Dict[str, object]] = []

    def row(op: str, work: str, n: int, ours: float, theirs: float, vtk_name: str) -> None:
        rows.append({"op": op, "work": work, "n": n, "tetloc_s": ours, "vtk_s": theirs, "vtk": vtk_name,
                     "ratio": theirs / ours})
        print(f"  {op}: tetloc {ours:.3f} s, {vtk_name} {theirs:.3f} s: {theirs / ours:.1f}x", file=sys.stderr)

    # Resample.
    d = a.dims
    ours, img = timed(lambda: tetloc.resample_to_image(mesh, dims=(d, d, d), backend=a.backend), a.repeats)
    f = vtk.vtkResampleToImage()
    f.SetInputDataObject(grid)
    f.SetUseInputBounds(True)
    f.SetSamplingDimensions(d, d, d)
    theirs, _ = timed(f.Update)
    row("resample", f"{d}^3 grid, every field", d**3, ours, theirs, "vtkResampleToImage")

    # Probe.
    pts = rng.uniform(lo, hi, size=(a.probe_points, 3)).astype(np.float32)
    ours, _ = timed(lambda: tetloc.probe(mesh, pts, backend=a.backend), a.repeats)
    target = vtk_points(pts)
    f = vtk.vtkResampleWithDataSet()
    f.SetInputDataObject(target)
    f.SetSourceData(grid)
    theirs, _ = timed(f.Update)
    row("probe", f"{a.probe_points} random points of the box, every field", a.probe_points, ours, theirs,
        "vtkResampleWithDataSet")

    # Trace: seeds at random tets' centres.
    centres = np.asarray(grid.cell_centers().points)[rng.integers(0, grid.n_cells, a.seeds)].astype(np.float32)
    trace = lambda: tetloc.trace(mesh, "v", centres, step=step, max_steps=a.max_steps, backend=a.backend)  # noqa: E731
    ours, lines = timed(trace, a.repeats)
    t = vtk.vtkStreamTracer()
    t.SetInputData(grid)
    t.SetSourceData(vtk_points(centres))
    t.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "v")
    t.SetIntegratorTypeToRungeKutta4()
    t.SetIntegrationStepUnit(vtk.vtkStreamTracer.LENGTH_UNIT)
    t.SetInitialIntegrationStep(step)
    t.SetMaximumNumberOfSteps(a.max_steps)
    t.SetMaximumPropagation(1e30)
    t.SetComputeVorticity(False)
    theirs, _ = timed(t.Update)
    steps = len(lines["points"]) - (len(lines["offsets"]) - 1)
    vtk_steps = t.GetOutput().GetNumberOfPoints() - t.GetOutput().GetNumberOfLines()
    row("trace", f"{a.seeds} seeds, RK4, at most {a.max_steps} steps ({steps} steps here, {vtk_steps} in VTK)",
        steps, ours, theirs, "vtkStreamTracer")

    info = {"mesh": str(path), "tets": mesh.n_cells, "backend": a.backend, "cpus": os.cpu_count(),
            "cpu": platform.processor(), "vtk": vtk.vtkVersion.GetVTKVersion(), "tetloc": tetloc.__version__}
    print(f"\n{path.name} ({mesh.n_cells} tets), tetloc {a.backend} vs VTK {info['vtk']}, {os.cpu_count()} CPUs")
    print(f"| operation | work | tetloc (s) | VTK (s) | VTK filter | tetloc / VTK speed |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['op']} | {r['work']} | {r['tetloc_s']:.3f} | {r['vtk_s']:.3f} | {r['vtk']} | {r['ratio']:.1f}x |")
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps({"machine": info, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
