#!/usr/bin/env python3
"""tetloc's resample, probe and trace against VTK's filters, same machine, same run.

On one mesh (by default ``torus_s.vtu`` of the oracle data, or ``--mesh FILE``, or ``--fusion
1.4M`` for the shape `tetloc gen fusion --vector` writes, with its tokamak-like field `v`:
toroidal plus poloidal flow, streamlines winding around the torus) with, when it has no `v`,
a swirl vector field added, v = (-y + 0.2 x, x + 0.2 y, 0.3) over the mesh's centred
coordinates:

  - ``tetloc.resample_to_image`` of every field onto an N^3 grid vs ``vtkResampleToImage``;
  - ``tetloc.probe`` at K random points of the bounding box vs ``vtkResampleWithDataSet``, or
    with ``--probe-mesh N`` at the vertices of a second fusion mesh of N tets (seed 2);
  - ``tetloc.trace`` (RK4, a fixed step of a tenth of the mean edge) from S seeds for at most
    M steps vs ``vtkStreamTracer`` with the same integrator, step and limits;

each with the locator build included (VTK builds its own): every run, tetloc's and VTK's,
starts from a fresh copy of the mesh, because both keep what their searches build on the
mesh object (tetloc its face neighbours, VTK its point locator and cell links). The best of
``--repeats`` runs for tetloc, one run for VTK; printing seconds, points (or steps) per second and the ratio. VTK's
slow filters can run on a part of the work (``--vtk-fraction``: the first fraction of the
probe points and seeds, and of the grid's z slices), their time scaled up linearly, and the
table says so.

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
from typing import Callable, Dict, List, Optional

import numpy as np

import tetloc

REPO = pathlib.Path(__file__).resolve().parents[2]


CPU_S: Dict[str, float] = {}


def timed(f: Callable[..., object], repeats: int = 1, key: str = "", setup: Optional[Callable[[], object]] = None):
    """(best seconds over `repeats`, the last result); with `key`, the process's CPU seconds
    (user + system, every thread) of that best run go to CPU_S[key]. With `setup`, each run
    is `f(setup())`, setup untimed."""
    best, out = float("inf"), None
    for _ in range(repeats):
        arg = (setup(),) if setup else ()
        t, c = time.perf_counter(), time.process_time()
        out = f(*arg)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        if wall < best:
            best = wall
            if key:
                CPU_S[key] = cpu
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


def cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mesh", help="a mesh file (default: torus_s.vtu of TETLOC_DATA or ../shared/data)")
    ap.add_argument("--fusion", help="generate the fusion shape of this many tets instead (e.g. 1.4M)")
    ap.add_argument("--dims", type=int, default=128, help="resample grid points per axis (default 128)")
    ap.add_argument("--probe-points", type=int, default=1_000_000, help="probe points (default 1M)")
    ap.add_argument("--seeds", type=int, default=1000, help="streamline seeds (default 1000)")
    ap.add_argument("--max-steps", type=int, default=1000, help="steps per streamline (default 1000)")
    ap.add_argument("--probe-mesh", help="probe the vertices of a second fusion mesh of this many tets (e.g. 5.6M)")
    ap.add_argument("--vtk-fraction", type=float, default=1.0, help="VTK's share of the work, scaled up (default 1)")
    ap.add_argument("--backend", default="cpu", help="tetloc's backend (default cpu)")
    ap.add_argument("--repeats", type=int, default=3, help="tetloc runs, best taken (default 3)")
    ap.add_argument("--json", help="also write the results here")
    ap.add_argument("--no-vtk", action="store_true", help="time tetloc only (VTK's columns are NaN)")
    a = ap.parse_args()
    load_start = os.getloadavg()

    import pyvista as pv
    import vtk

    tmp = pathlib.Path(os.environ.get("TMPDIR", "/tmp"))

    def generated(tets: str, seed: int) -> pathlib.Path:
        path = tmp / f"tetloc-bench-fusion-{tets}-v-{seed}.vtu"
        if not path.exists():
            cli = next((str(p) for p in (REPO / "target/release/tetloc", REPO / "target/debug/tetloc") if p.is_file()))
            subprocess.run([cli, "gen", "fusion", "--tets", tets, "--seed", str(seed), "--vector", "-o", str(path)],
                           check=True, stderr=subprocess.DEVNULL)
        return path

    if a.fusion:
        path = generated(a.fusion, 1)
    elif a.mesh:
        path = pathlib.Path(a.mesh)
    else:
        data = pathlib.Path(os.environ.get("TETLOC_DATA") or REPO.parent / "shared" / "data")
        path = data / "torus_s.vtu"
    grid = pv.read(path)
    lo, hi = np.asarray(grid.bounds).reshape(3, 2).T
    if "v" not in grid.point_data:
        grid.point_data["v"] = swirl(np.asarray(grid.points), (lo + hi) / 2, float(np.max(hi - lo)) / 2)
    grid.point_data.active_vectors_name = "v"
    mesh = tetloc.Mesh.from_pyvista(grid)
    print(f"{path.name}: {mesh.n_cells} tets, {mesh.n_points} points; fields {list(mesh.point_data)}", file=sys.stderr)
    step = 0.1 * mesh.info()["mesh"]["mean_edge_length"]
    rng = np.random.default_rng(1)
    rows: List[Dict[str, object]] = []
    frac = a.vtk_fraction

    def vtk_time(run: Callable[[float], float]) -> float:
        """VTK's seconds for the whole work: one run, or with a fraction f < 1 runs on f/2 and f
        and the line through them (a fixed cost, its locator's build, plus a cost per item)."""
        if a.no_vtk:
            return float("nan")
        if frac >= 1.0:
            return run(1.0)
        t1, t2 = run(frac / 2), run(frac)
        per = max(t2 - t1, 0.0) / (frac / 2)
        return t2 + per * (1.0 - frac)

    def row(op: str, work: str, n: int, ours: float, theirs: float, vtk_name: str) -> None:
        if frac < 1.0:
            work += f"; VTK ran {frac / 2:.3g} and {frac:.3g} of it, its time extrapolated linearly"
        cpu = CPU_S.get(op, float("nan"))
        rows.append({"op": op, "work": work, "n": n, "tetloc_s": ours, "tetloc_cpu_s": cpu, "vtk_s": theirs,
                     "vtk": vtk_name, "ratio": theirs / ours})
        print(f"  {op}: tetloc {ours:.3f} s ({cpu:.2f} s CPU), {vtk_name} {theirs:.3f} s: {theirs / ours:.1f}x",
              file=sys.stderr)

    # Every tetloc run gets a mesh of its own, converted untimed: a mesh keeps what a locator
    # derives from it (the face neighbours), which VTK's filters rebuild on every run.
    def fresh() -> "tetloc.Mesh":
        return tetloc.Mesh.from_pyvista(grid)

    # VTK likewise: a dataset keeps the point locator and cell links its filters build, so
    # each VTK run gets a deep copy of a grid none has searched yet (made here, untimed).
    pristine = grid.copy(deep=True)

    def vtk_source():
        return pristine.copy(deep=True)

    build, _ = timed(lambda m: tetloc.Locator(m, backend=a.backend), a.repeats, setup=fresh)
    print(f"  locator build alone: {build:.3f} s", file=sys.stderr)

    # Resample.
    d = a.dims
    ours, img = timed(lambda m: tetloc.resample_to_image(m, dims=(d, d, d), backend=a.backend), a.repeats,
                     "resample", fresh)

    def vtk_resample(share: float) -> float:
        # The same grid as tetloc's (the bounds nudged inwards by 1e-6, as UseInputBounds
        # does), its first z slices when VTK runs on a part (whole slices: z-slab fractions).
        nz = max(1, round(d * share))
        b = np.asarray(grid.bounds, dtype=float).reshape(3, 2)
        mid, half = b.mean(axis=1), 0.5 * (b[:, 1] - b[:, 0]) * (1 - 1e-6)
        lo_b, hi_b = mid - half, mid + half
        hi_b[2] = lo_b[2] + (hi_b[2] - lo_b[2]) * (nz - 1) / max(d - 1, 1)
        f = vtk.vtkResampleToImage()
        f.SetInputDataObject(vtk_source())
        f.SetUseInputBounds(False)
        f.SetSamplingBounds(lo_b[0], hi_b[0], lo_b[1], hi_b[1], lo_b[2], hi_b[2])
        f.SetSamplingDimensions(d, d, nz)
        return timed(f.Update)[0]

    row("resample", f"{d}^3 grid, every field", d**3, ours, vtk_time(vtk_resample), "vtkResampleToImage")

    # Probe.
    if a.probe_mesh:
        pts = np.asarray(pv.read(generated(a.probe_mesh, 2)).points, dtype=np.float32)
        what = f"the {len(pts)} vertices of a second fusion mesh ({a.probe_mesh} tets, seed 2)"
    else:
        pts = rng.uniform(lo, hi, size=(a.probe_points, 3)).astype(np.float32)
        what = f"{a.probe_points} random points of the box"
    ours, _ = timed(lambda m: tetloc.probe(m, pts, backend=a.backend), a.repeats, "probe", fresh)

    def vtk_probe(share: float) -> float:
        f = vtk.vtkResampleWithDataSet()
        f.SetInputDataObject(vtk_points(pts[: max(1, round(len(pts) * share))]))
        f.SetSourceData(vtk_source())
        return timed(f.Update)[0]

    row("probe", f"{what}, every field", len(pts), ours, vtk_time(vtk_probe), "vtkResampleWithDataSet")

    # Trace: seeds at random tets' centres.
    centres = np.asarray(grid.cell_centers().points)[rng.integers(0, grid.n_cells, a.seeds)].astype(np.float32)
    trace = lambda m: tetloc.trace(m, "v", centres, step=step, max_steps=a.max_steps, backend=a.backend)  # noqa: E731
    ours, lines = timed(trace, a.repeats, "trace", fresh)
    tracer = {}

    def vtk_trace(share: float) -> float:
        t = vtk.vtkStreamTracer()
        t.SetInputData(vtk_source())
        tracer["seeds"] = max(1, round(a.seeds * share))
        t.SetSourceData(vtk_points(centres[: tracer["seeds"]]))
        t.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "v")
        t.SetIntegratorTypeToRungeKutta4()
        t.SetIntegrationStepUnit(vtk.vtkStreamTracer.LENGTH_UNIT)
        t.SetInitialIntegrationStep(step)
        t.SetMaximumNumberOfSteps(a.max_steps)
        t.SetMaximumPropagation(1e30)
        t.SetComputeVorticity(False)
        tracer["t"] = t
        return timed(t.Update)[0]

    theirs = vtk_time(vtk_trace)
    steps = len(lines["points"]) - (len(lines["offsets"]) - 1)
    work = f"{a.seeds} seeds, RK4, at most {a.max_steps} steps ({steps} steps here"
    if "t" in tracer:
        t, ks = tracer["t"], tracer["seeds"]
        vtk_steps = t.GetOutput().GetNumberOfPoints() - t.GetOutput().GetNumberOfLines()
        first = np.asarray(lines["SeedIds"]) < ks  # tetloc's lines from VTK's seeds
        ours_part = int((np.diff(lines["offsets"]) - 1)[first].sum())
        work += f"; {vtk_steps} in VTK against {ours_part} of tetloc's on the same seeds"
    row("trace", work + ")", steps, ours, theirs, "vtkStreamTracer")

    info = {"mesh": str(path), "tets": mesh.n_cells, "backend": a.backend, "cpus": os.cpu_count(),
            "cpu": cpu_model(), "vtk": vtk.vtkVersion.GetVTKVersion(), "tetloc": tetloc.__version__,
            "locator_build_s": build, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "load_average": os.getloadavg(), "load_average_start": load_start}
    print(f"\n{path.name} ({mesh.n_cells} tets), tetloc {a.backend} vs VTK {info['vtk']}, {os.cpu_count()} CPUs "
          f"({info['cpu']}, load average {load_start[0]:.1f} at the start, {info['load_average'][0]:.1f} at the end), {info['date']}; tetloc's times "
          f"include its locator build ({build:.3f} s alone)")
    print(f"| operation | work | tetloc (s) | tetloc CPU (s) | VTK (s) | VTK filter | tetloc / VTK speed |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['op']} | {r['work']} | {r['tetloc_s']:.3f} | {r['tetloc_cpu_s']:.2f} | {r['vtk_s']:.3f} | "
              f"{r['vtk']} | {r['ratio']:.1f}x |")
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps({"machine": info, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
