#!/usr/bin/env python3
"""tetloc.Locator.locate against the Python peers, same machine, same run.

Default mode: the `fusion` shape of about 1.4M tets (written by `tetloc gen fusion`) and 1M
random points inside it, located by

  - tetloc ``Locator.locate`` (cpu, and soft-bvh when a GPU is there),
  - pyvista ``find_containing_cell`` (a cached vtkStaticCellLocator, one FindCell per point),
  - VTK ``vtkProbeFilter`` with a ``vtkStaticCellLocator`` and with a ``vtkCellTreeLocator``,
  - scipy ``Delaunay.find_simplex`` on the Delaunay mesh of the same vertices,

printing build and locate times, points/s and tetloc's ratio to each, with the machine and
versions. ``--gpu`` measures the numpy-array path on a GPU instead: points/s of
``Locator.locate`` / ``sample`` from float32 and float64 arrays, every transfer included.
``--sweep`` measures small batches instead: microseconds a point of a warm ``Locator.locate``
(cpu) for batches of 1 to 1M random points (each call a fresh batch), against pyvista's
``find_containing_cell`` and a prebuilt ``vtkCellTreeLocator`` (``FindCell`` per point); the
whole sweep ``--runs`` times, each cell the median of the runs.

Run it from the repository root:  python python/benchmarks/bench_locate.py [--json FILE]
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


def count(text: str) -> int:
    """1.4M, 200k, 1000 -> int."""
    scale = {"k": 1e3, "m": 1e6, "g": 1e9}.get(text[-1].lower(), 1)
    return int(float(text.rstrip("kKmMgG")) * scale)


def machine() -> Dict[str, object]:
    cpu = platform.processor()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    info: Dict[str, object] = {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "python": platform.python_version(),
        "tetloc": tetloc.__version__,
        "numpy": np.__version__,
        "devices": [f"{d['name']} ({d['device_type']}, {d['driver']})" for d in tetloc.devices()],
    }
    for name in ("vtk", "pyvista", "scipy"):
        try:
            info[name] = __import__(name).__version__
        except ImportError:
            info[name] = None
    return info


def fusion_mesh(tets: str, cli: Optional[str], cache: pathlib.Path) -> pathlib.Path:
    """The fusion shape written by `tetloc gen` (cached)."""
    path = cache / f"fusion-{tets}.vtu"
    if not path.exists():
        cli = cli or next(
            (str(p) for p in (REPO / "target/release/tetloc", REPO / "target/debug/tetloc") if p.is_file()), None
        )
        if cli is None:
            sys.exit("no tetloc binary: cargo build --release -p tetloc-cli (or --cli PATH, or --mesh FILE)")
        cache.mkdir(parents=True, exist_ok=True)
        subprocess.run([cli, "gen", "fusion", "--tets", tets, "-o", str(path)], check=True)
    return path


def random_points_inside(mesh: tetloc.Mesh, n: int, seed: int) -> np.ndarray:
    """`n` points, each uniform in a random tet (the CLI's `random` query set), float32."""
    rng = np.random.default_rng(seed)
    corners = mesh.points.astype(np.float64)[mesh.tets[rng.integers(0, mesh.n_tets, n)]]
    w = -np.log(rng.random((n, 4)))  # Dirichlet(1,1,1,1): uniform barycentrics
    w /= w.sum(axis=1, keepdims=True)
    return np.einsum("nk,nkd->nd", w, corners).astype(np.float32)


def timed(f: Callable[[], object], repeats: int = 1):
    """(best seconds over `repeats`, the last result)."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


class Row:
    def __init__(self, name: str, build: Optional[float], locate: float, n: int, ids=None, note: str = ""):
        self.name, self.build, self.locate, self.n, self.ids, self.note = name, build, locate, n, ids, note
        print(f"  measured {name}: build {build or 0:.3f} s, locate {locate:.3f} s", file=sys.stderr, flush=True)

    @property
    def rate(self) -> float:
        return self.n / self.locate

    def as_dict(self) -> Dict[str, object]:
        return {"name": self.name, "build_s": self.build, "locate_s": self.locate, "points": self.n,
                "points_per_s": self.rate, "note": self.note}


def vtk_probe(grid, points: np.ndarray, locator_class, repeats: int):
    """(locator build s, probe-only s, probe total s, ids): vtkProbeFilter with `locator_class`
    as the cell locator prototype. The probe builds its locator on every update: the build is
    timed alone (a 1-point probe), the probe-only time is the difference."""
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

    source = grid.copy()
    source.clear_data()
    source.cell_data["tet"] = np.arange(source.n_cells, dtype=np.int32)

    def probe(p: np.ndarray):
        pts = vtk.vtkPoints()
        pts.SetData(numpy_to_vtk(p, deep=False))
        poly = vtk.vtkPolyData()
        poly.SetPoints(pts)
        f = vtk.vtkProbeFilter()
        f.SetInputData(poly)
        f.SetSourceData(source)
        f.SetCellLocator(locator_class()) if hasattr(f, "SetCellLocator") else f.SetCellLocatorPrototype(
            locator_class()
        )
        f.Update()
        out = f.GetOutput()
        ids = vtk_to_numpy(out.GetPointData().GetArray("tet")).astype(np.int32)
        valid = vtk_to_numpy(out.GetPointData().GetArray(f.GetValidPointMaskArrayName())).astype(bool)
        return np.where(valid, ids, -1)

    build, _ = timed(lambda: probe(points[:1]), repeats)
    total, ids = timed(lambda: probe(points), repeats)
    return build, max(total - build, 1e-9), total, ids


def peers(mesh_path: pathlib.Path, mesh: tetloc.Mesh, points: np.ndarray, repeats: int) -> List[Row]:
    rows: List[Row] = []
    try:
        import pyvista as pv
        import vtk

        have_vtk = True
    except ImportError as e:
        print(f"skipping the VTK peers: {e}", file=sys.stderr)
        have_vtk = False
    if have_vtk:
        grid = pv.read(mesh_path)
        print(f"VTK SMP backend {vtk.vtkSMPTools.GetBackend()}, "
              f"{vtk.vtkSMPTools.GetEstimatedNumberOfThreads()} threads", file=sys.stderr)
        # pyvista caches its locator on the dataset: the first call builds it.
        build, _ = timed(lambda: grid.find_containing_cell(points[:1]))
        loc_s, ids = timed(lambda: grid.find_containing_cell(points))
        rows.append(Row("pyvista find_containing_cell", build, loc_s, len(points), ids, "Python loop of FindCell"))
        for cls in (vtk.vtkStaticCellLocator, vtk.vtkCellTreeLocator):
            build, probe_s, total, ids = vtk_probe(grid, points, cls, repeats)
            rows.append(Row(f"vtkProbeFilter + {cls.__name__}", build, probe_s, len(points), ids,
                            f"probe total {total:.2f} s"))
    try:
        from scipy.spatial import Delaunay

        build, tri = timed(lambda: Delaunay(mesh.points.astype(np.float64)))
        loc_s, _ = timed(lambda: tri.find_simplex(points.astype(np.float64)), repeats)
        rows.append(Row("scipy Delaunay.find_simplex", build, loc_s, len(points), None,
                        f"its own Delaunay mesh: {len(tri.simplices)} tets"))
    except ImportError as e:
        print(f"skipping scipy: {e}", file=sys.stderr)
    return rows


def tetloc_rows(mesh: tetloc.Mesh, points: np.ndarray, backends: List[str], repeats: int) -> List[Row]:
    rows = []
    for backend in backends:
        build, loc = timed(lambda: tetloc.Locator(mesh, backend=backend))
        loc.locate(points)  # warm-up (pipelines, page faults)
        s, ids = timed(lambda: loc.locate(points), repeats)
        mem = loc.memory()
        rows.append(Row(f"tetloc {backend}", build, s, len(points), ids,
                        f"peak {mem['peak_bytes'] / 2**20:.0f} MiB ({mem['on']})"))
    return rows


def print_table(rows: List[Row], ours: Row) -> None:
    print(f"{'method':<40} {'build s':>8} {'locate s':>9} {'points/s':>10} {'tetloc locate ×':>16}  note")
    for r in rows:
        ratio = ours.rate / r.rate
        build = "-" if r.build is None else f"{r.build:.3f}"
        print(f"{r.name:<40} {build:>8} {r.locate:>9.3f} {r.rate / 1e6:>9.3f}M {ratio:>15.1f}×  {r.note}")


def compare(args) -> Dict[str, object]:
    path = pathlib.Path(args.mesh) if args.mesh else fusion_mesh(args.tets, args.cli, REPO / "target/bench")
    mesh = tetloc.read(path)
    points = random_points_inside(mesh, count(args.points), args.seed)
    print(f"mesh {path}: {mesh.n_cells} tets, {mesh.n_points} points; {len(points)} random points inside")
    backends = ["cpu"]
    if any(d["device_type"] != "cpu" for d in tetloc.devices()):
        backends.append("soft-bvh")
    ours = tetloc_rows(mesh, points, backends, args.repeats)
    others = peers(path, mesh, points, args.repeats)
    cpu = ours[0]
    print_table(ours + others, cpu)
    for r in others:
        if r.ids is not None:
            same = np.mean(np.asarray(r.ids) == cpu.ids)
            print(f"  {r.name}: same id as tetloc for {100 * same:.2f} % of points "
                  "(VTK accepts points up to ~1e-3 outside a tet)")
    best = max(others, key=lambda r: r.rate) if others else None
    if best:
        e2e = lambda r: r.n / (r.locate + (r.build or 0))  # noqa: E731
        best_e2e = max(others, key=e2e)
        print(f"tetloc cpu locate vs the best peer ({best.name}): {cpu.rate / best.rate:.1f}×; "
              f"build + locate vs the best peer's ({best_e2e.name}): {e2e(cpu) / e2e(best_e2e):.1f}×")
    return {"mesh": str(path), "tets": mesh.n_cells, "rows": [r.as_dict() for r in ours + others]}


def gpu(args) -> Dict[str, object]:
    """The numpy-array path on a GPU: points/s with transfers, from float32 and float64 arrays
    (`f64`: float32 values widened, rounded back to float32 on this float32 mesh; `f64 mesh`:
    the mesh's vertices one float64 ulp off float32, so float64 points keep their precision:
    exact decisions on the CPU, every GPU answer re-tested exactly on the host)."""
    path = pathlib.Path(args.mesh) if args.mesh else fusion_mesh(args.tets, args.cli, REPO / "target/bench")
    mesh = tetloc.read(path)
    field = next(iter(mesh.point_data), None)
    sizes = [count(s) for s in args.sizes.split(",")]
    points = random_points_inside(mesh, max(sizes), args.seed)
    print(f"mesh {path}: {mesh.n_cells} cells, {mesh.n_tets} tets; point field {field!r}")
    # The same mesh with float64 vertices that float32 cannot hold.
    mesh64 = tetloc.Mesh(
        np.nextafter(mesh.points64, np.inf),
        mesh.cells,
        point_data={field: mesh.field(field)} if field else None,
        celltypes=mesh.celltypes,
    )
    rows = []
    for backend in args.backends.split(","):
        build, loc = timed(lambda: tetloc.Locator(mesh, backend=backend))
        loc64 = tetloc.Locator(mesh64, backend=backend)
        mem = loc.memory()
        print(f"{backend}: build {build:.2f} s, final {mem['final_bytes'] / 2**20:.0f} MiB, "
              f"peak {mem['peak_bytes'] / 2**20:.0f} MiB ({mem['on']})")
        loc.locate(points[: sizes[0]])  # warm-up
        for n in sizes:
            p32 = points[:n]
            p64 = p32.astype(np.float64)
            cases = {
                "locate f32": lambda: loc.locate(p32),
                "locate f64": lambda: loc.locate(p64),
                "locate f64 mesh": lambda: loc64.locate(p64),
            }
            if field:
                cases["sample f32"] = lambda: loc.sample(p32, field)
                cases["sample f64 mesh"] = lambda: loc64.sample(p64, field)
            for case, f in cases.items():
                s, _ = timed(f, args.repeats)
                rows.append({"backend": backend, "case": case, "points": n, "seconds": s, "points_per_s": n / s})
                print(f"  {case:<15} {n:>11,} points {s:8.4f} s  {n / s / 1e6:9.1f} M points/s")
    return {"mesh": str(path), "tets": mesh.n_cells, "rows": rows}


def sweep(args) -> Dict[str, object]:
    """Microseconds a point by batch size (see the module's documentation)."""
    path = pathlib.Path(args.mesh) if args.mesh else fusion_mesh(args.tets, args.cli, REPO / "target/bench")
    mesh = tetloc.read(str(path))
    sizes = [count(s) for s in args.batches.split(",")]
    pool = random_points_inside(mesh, max(sizes) * 4, args.seed)
    loc = tetloc.Locator(mesh, backend="cpu")
    loc.locate(pool[:1000])  # warm: the search is built

    def per_point(call: Callable[[np.ndarray], object], n: int, budget: float) -> float:
        """Median over calls on fresh batches of n points (as many calls as fit in about
        `budget` seconds, at least 3), in microseconds a point."""
        times = []
        start, k = time.perf_counter(), 0
        while k < 3 or (time.perf_counter() - start < budget and k < 2000):
            batch = pool[(k * n) % (len(pool) - n):][:n]
            t = time.perf_counter()
            call(batch)
            times.append(time.perf_counter() - t)
            k += 1
        return float(np.median(times)) / n * 1e6

    peers: Dict[str, Callable[[np.ndarray], object]] = {"tetloc cpu": loc.locate}
    try:
        import pyvista as pv
        import vtk

        grid = pv.read(path)
        grid.find_containing_cell(pool[:1])  # pyvista caches its locator: built here
        peers["pyvista find_containing_cell"] = grid.find_containing_cell
        tree = vtk.vtkCellTreeLocator()
        tree.SetDataSet(grid)
        tree.BuildLocator()
        peers["vtkCellTreeLocator.FindCell"] = lambda b: [tree.FindCell(p) for p in b.astype(np.float64).tolist()]
    except ImportError as e:
        print(f"skipping the VTK peers: {e}", file=sys.stderr)
    print(f"{path.name}: {mesh.n_cells} tets", file=sys.stderr)
    # The whole sweep `runs` times (the machine may be shared), then each cell's median.
    runs: List[Dict[int, Dict[str, float]]] = []
    loads = []
    for run in range(args.runs):
        loads.append(os.getloadavg()[0])
        print(f"run {run + 1} of {args.runs}, load {loads[-1]:.1f}", file=sys.stderr)
        runs.append({})
        for n in sizes:
            # VTK's per-point loops take seconds a call beyond 100k points: left out there.
            runs[-1][n] = {name: per_point(call, n, args.budget) if name == "tetloc cpu" or n <= 100_000
                           else float("nan") for name, call in peers.items()}
            print(f"  {n:>9,}: " + ", ".join(f"{name} {us:.3f}" for name, us in runs[-1][n].items()),
                  file=sys.stderr, flush=True)
    rows = [{"batch": n, **{name: float(np.median([r[n][name] for r in runs])) for name in peers}} for n in sizes]
    vtk = "vtkCellTreeLocator.FindCell"
    print(f"median of {args.runs} runs, µs a point (load {', '.join(f'{x:.1f}' for x in loads)})")
    print("| batch | " + " | ".join(peers) + (" | VTK cell tree / tetloc |" if vtk in peers else " |"))
    print("|---|" + "---|" * (len(peers) + (vtk in peers)))
    for r in rows:
        ratio = f" {r[vtk] / r['tetloc cpu']:.1f}× |" if vtk in peers and r[vtk] == r[vtk] else (" - |" if vtk in peers else "")
        print(f"| {r['batch']:,} | " + " | ".join(f"{r[name]:.3f}" for name in peers) + " |" + ratio)
    return {"mesh": str(path), "tets": mesh.n_cells, "load_average": loads, "sweep": rows,
            "runs": [[{"batch": n, **r[n]} for n in sizes] for r in runs]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh", help="a mesh file instead of the generated fusion shape")
    ap.add_argument("--tets", default="1.4M", help="fusion size for `tetloc gen` (default 1.4M)")
    ap.add_argument("--points", default="1M", help="random points inside the mesh (default 1M)")
    ap.add_argument("--repeats", type=int, default=3, help="best of this many runs (default 3)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cli", help="the tetloc binary that writes the mesh (default target/release/tetloc)")
    ap.add_argument("--gpu", action="store_true", help="measure the numpy-array path on a GPU instead")
    ap.add_argument("--backends", default="soft-bvh,cpu", help="--gpu: backends (default soft-bvh,cpu)")
    ap.add_argument("--sizes", default="1M,10M,50M", help="--gpu: batch sizes (default 1M,10M,50M)")
    ap.add_argument("--sweep", action="store_true", help="small batches: µs a point by batch size (cpu, VTK)")
    ap.add_argument("--batches", default="1,10,100,1000,10k,100k,1M", help="--sweep: batch sizes")
    ap.add_argument("--budget", type=float, default=1.0, help="--sweep: seconds of calls per size and method")
    ap.add_argument("--runs", type=int, default=3, help="--sweep: whole sweeps; the table gives medians (default 3)")
    ap.add_argument("--json", help="also write the results as JSON to this file")
    args = ap.parse_args()
    info = machine()
    print(" ".join(f"{k}={v}" for k, v in info.items()))
    result = gpu(args) if args.gpu else sweep(args) if args.sweep else compare(args)
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"machine": info, **result}, indent=1))


if __name__ == "__main__":
    main()
