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

``--pathlines``: pathlines instead (``tetloc.trace(..., unsteady=True)``, RK4, half an
interval a step) of ``--particles`` particles over ``--path-steps`` steps of the generated
fusion mesh's flow ``v`` scaled in time by 1 + 0.5 sin(2 pi t / T), written once as a ``.pvd``
of ``.vtu`` files (tetloc reads each step from its file, inside the timing), against
vtkParticlePathFilter on the same steps held in memory (static mesh), run on
``--vtk-particles`` of the particles and scaled to all of them (the work is per particle).
``--reinject-every N``: both inject the seeds again every N steps.

  python python/benchmarks/bench_time.py --pathlines --fusion 200k --particles 100k --path-steps 100 [--cold]

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


def count(s: str) -> int:
    s = s.lower()
    mult = {"k": 1_000, "m": 1_000_000}.get(s[-1:], 1)
    return int(float(s.rstrip("km")) * mult)


def pathlines(args) -> None:
    cli = os.environ.get("TETLOC_CLI") or str(REPO / "target/release/tetloc")
    tmp = pathlib.Path(tempfile.gettempdir()) / f"bench_paths_{args.fusion}_{args.path_steps}"
    tmp.mkdir(exist_ok=True)
    vtu = tmp / "fusion.vtu"
    if not vtu.exists():
        subprocess.run([cli, "gen", "fusion", "--tets", args.fusion, "--vector", "-o", str(vtu)], check=True)
    mesh = tetloc.read(vtu)
    v = np.asarray(mesh.field("v"), dtype=np.float64)
    lo, hi = np.reshape(mesh.bounds, (3, 2)).T
    speed = float(np.median(np.linalg.norm(v, axis=1)))
    # A tenth of the mesh's extent at the median speed: most particles stay inside.
    total = 0.1 * float(np.linalg.norm(hi - lo)) / speed
    times = np.linspace(0.0, total, args.path_steps + 1)
    scale = 1 + 0.5 * np.sin(2 * np.pi * times / total)
    pvd = tmp / "series.pvd"
    grid = mesh.to_pyvista()
    if not pvd.exists():
        entries = []
        for k, t in enumerate(times):
            grid.point_data["v"] = (v * scale[k]).astype(np.float32)
            grid.save(tmp / f"step_{k}.vtu")
            entries.append(f'<DataSet timestep="{float(t)!r}" part="0" file="step_{k}.vtu"/>')
        pvd.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n'
                       + "\n".join(entries) + "\n</Collection>\n</VTKFile>\n")
    n = count(args.particles)
    rng = np.random.default_rng(2)
    loc = tetloc.Locator(mesh, backend="cpu")
    seeds = np.zeros((0, 3), np.float32)
    while len(seeds) < n:
        pts = rng.uniform(lo, hi, size=(4 * n, 3)).astype(np.float32)
        seeds = np.concatenate([seeds, pts[loc.locate(pts) >= 0]])
    seeds = seeds[:n]

    if args.cold:
        # The step files out of the page cache, as a series on disk is on its first read.
        os.sync()
        pathlib.Path("/proc/sys/vm/drop_caches").write_text("3\n")
    series = tetloc.read(pvd)
    t0 = time.perf_counter()
    ours = tetloc.trace(series, "v", seeds, unsteady=True, backend=args.backend, reinject_every=args.reinject_every)
    t_ours = time.perf_counter() - t0
    n_points = len(ours["points"])
    print(f"tetloc: {n} particles, {len(ours['offsets']) - 1} lines, {n_points} points in {t_ours:.2f} s "
          f"(reading {len(times)} step files included)")

    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase

    sddp = vtk.vtkStreamingDemandDrivenPipeline
    base = grid.copy()
    grids = []
    for k in range(len(times)):
        g = vtk.vtkUnstructuredGrid()
        g.ShallowCopy(base)
        a = numpy_to_vtk((v * scale[k]).astype(np.float32), deep=True)
        a.SetName("v")
        g.GetPointData().AddArray(a)
        g.GetPointData().SetActiveVectors("v")
        grids.append(g)

    class Steps(VTKPythonAlgorithmBase):
        def __init__(self) -> None:
            # Composite, a fresh block a step: vtkParticlePathFilter keeps a plain dataset input
            # by reference, so the source's reused output object would stand for both ends of
            # an interval (scripts/vtk_pathlines.py).
            VTKPythonAlgorithmBase.__init__(self, nInputPorts=0, nOutputPorts=1, outputType="vtkMultiBlockDataSet")

        def RequestInformation(self, request, in_info, out_info):
            info = out_info.GetInformationObject(0)
            info.Set(sddp.TIME_STEPS(), list(times), len(times))
            info.Set(sddp.TIME_RANGE(), [times[0], times[-1]], 2)
            return 1

        def RequestData(self, request, in_info, out_info):
            info = out_info.GetInformationObject(0)
            t = info.Get(sddp.UPDATE_TIME_STEP()) if info.Has(sddp.UPDATE_TIME_STEP()) else times[0]
            k = int(np.argmin(np.abs(times - t)))
            block = vtk.vtkUnstructuredGrid()
            block.ShallowCopy(grids[k])
            out = vtk.vtkMultiBlockDataSet.GetData(out_info)
            out.SetNumberOfBlocks(1)
            out.SetBlock(0, block)
            out.GetInformation().Set(vtk.vtkDataObject.DATA_TIME_STEP(), times[k])
            return 1

    m = min(count(args.vtk_particles), n)
    poly = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(seeds[:m].astype(np.float64), deep=True))
    poly.SetPoints(pts)
    src = Steps()
    f = vtk.vtkParticlePathFilter()
    f.SetInputConnection(0, src.GetOutputPort())
    f.SetInputData(1, poly)
    f.SetIntegratorType(1)
    f.SetMeshOverTimeToStatic()
    f.SetForceReinjectionEveryNSteps(args.reinject_every)
    f.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "v")
    t0 = time.perf_counter()
    f.UpdateTimeStep(float(times[-1]))
    t_vtk = (time.perf_counter() - t0) * n / m
    out = f.GetOutput()
    # The last points of the particles both keep to the end: the same positions.
    pd = out.GetPointData()
    ids = vtk_to_numpy(pd.GetArray("InjectedPointId"))
    age = vtk_to_numpy(pd.GetArray("ParticleAge"))
    vp = vtk_to_numpy(out.GetPoints().GetData())
    end_vtk = {int(i): p for i, a, p in zip(ids, age, vp) if abs(a - times[-1]) < 1e-3 * times[-1]}
    offs, seed_ids = ours["offsets"], ours["SeedIds"]
    # The first injection's particles (with reinjection, the lines that start at the start time).
    first = ours["IntegrationTime"][offs[:-1]] == times[0]
    diffs = [np.abs(ours["points"][offs[j + 1] - 1] - end_vtk[int(s)]).max()
             for j, s in enumerate(seed_ids)
             if first[j] and int(s) in end_vtk and ours["ReasonForTermination"][j] == 7]
    print(f"VTK vtkParticlePathFilter: {m} particles in {t_vtk * m / n:.2f} s, scaled to {n}: {t_vtk:.1f} s")
    if diffs:
        print(f"  end points of {len(diffs)} particles both carried to the end: max |diff| {max(diffs):.2e}")
    print(f"{vtu.name}: {mesh.n_cells} cells, {len(times) - 1} steps, {n} seeds "
          f"(injected every {args.reinject_every or 'no'} steps again): "
          f"tetloc {t_ours:.2f} s, VTK {t_vtk:.1f} s (scaled from {m}), tetloc is {t_vtk / t_ours:.1f}x faster")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh")
    ap.add_argument("--fusion", default="1.4M")
    ap.add_argument("--points", type=float, default=1e6)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--sample-steps", type=int, default=3, help="steps the slow peers run (scaled up)")
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--json")
    ap.add_argument("--no-peers", action="store_true", help="tetloc's rows only (scipy and VTK take hours at 12M)")
    ap.add_argument("--pathlines", action="store_true", help="the pathline benchmark instead")
    ap.add_argument("--particles", default="100k")
    ap.add_argument("--path-steps", type=int, default=100)
    ap.add_argument("--vtk-particles", default="5k", help="particles VTK runs (scaled up)")
    ap.add_argument("--reinject-every", type=int, default=0,
                    help="pathlines: inject the seeds again every N steps (both tools)")
    ap.add_argument("--cold", action="store_true",
                    help="pathlines: drop the page cache before tetloc reads the steps (needs root)")
    args = ap.parse_args()
    if args.pathlines:
        return pathlines(args)

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

    # The same through StepWeights: on a GPU backend the weights stay on the device and each
    # batch of steps is interpolated there (float32 steps in, float32 values out).
    t0 = time.perf_counter()
    sw = loc.step_weights(pts)
    t_sw = time.perf_counter() - t0
    batch = max(1, (256 << 20) // (4 * len(base)))
    t_apply = 0.0
    t0 = time.perf_counter()
    for s in range(0, len(times), batch):
        values = np.stack([step(t) for t in times[s : s + batch]]).astype(np.float32)
        t1 = time.perf_counter()
        got_sw = sw.apply(values)
        t_apply += time.perf_counter() - t1
    total = t_sw + time.perf_counter() - t0
    rows[f"tetloc step_weights on {sw.device}"] = (
        total, args.steps, f"weights once {t_sw:.2f} s, apply {t_apply:.2f} s: {args.steps / t_apply:.0f} steps/s"
    )
    inside = ~np.isnan(got_sw[-1])
    print(f"step_weights vs weights at the last step: max |diff| {np.abs(got_sw[-1][inside] - check[inside]).max():.3g}")
    if args.no_peers:
        report(args, path, mesh, pts, loc, rows)
        return

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

    report(args, path, mesh, pts, loc, rows)


def report(args, path, mesh, pts, loc, rows) -> None:
    ours = rows["tetloc weights"][0]
    print(f"{path.name}: {mesh.n_cells} cells, {len(pts)} points, {args.steps} steps, backend {loc.backend}")
    for name, (sec, ran, note) in rows.items():
        print(f"  {name:36s} {sec:10.2f} s  ({ran} steps run; {note})  tetloc weights is {sec / ours:6.1f}x faster")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({k: v[0] for k, v in rows.items()}, indent=1))


if __name__ == "__main__":
    main()
