"""tetloc's cpu backend against VTK's probe on a polyhedral octree mesh (issue 35): time and
wrong cells of each, on the same random points.

    tetloc gen jets-octree --cells 1M -o oct.vtu
    python bench_octree_vtk.py oct.vtu [--points 1M] [--seed 1]

The points are uniform in the mesh's bounding box (the mesh is a sheared box, so some are
outside it). VTK: vtkProbeFilter with a vtkStaticCellLocator prototype, probing a cell array of
cell ids (its answer is the cell it found). tetloc: ``Locator(mesh, backend="cpu")``.

Truth comes from the generated geometry, not from either answer: the octree is an affine image
of a grid (``tetloc gen``'s octree), so cell 0's edges give the map; a point's preimage
(grid coordinates) lies in the true cell's grid box. An answer is wrong when the preimage is
outside the claimed cell's box (by more than 1e-9 of a cube: points on a face may go to either
side), or when it is -1 for a point inside the grid.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

import tetloc


def count(text: str) -> int:
    mult = {"k": 1e3, "M": 1e6}.get(text[-1], 1)
    return int(float(text.rstrip("kM")) * mult)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("--points", default="1M")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()

    # vtkPolyhedron's own face locator logs an error per call on these cells: silenced.
    vtk.vtkObject.GlobalWarningDisplayOff()
    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(a.mesh)
    r.Update()
    grid = r.GetOutput()
    pts = vtk_to_numpy(grid.GetPoints().GetData()).astype(np.float64)
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).astype(np.int64)
    offs = vtk_to_numpy(grid.GetCells().GetOffsetsArray()).astype(np.int64)
    n_cells = grid.GetNumberOfCells()

    # The affine map from cell 0 (a hexahedron at the grid's corner, VTK node order).
    c0 = conn[offs[0]:offs[1]]
    origin = pts[c0[0]]
    to_grid = np.linalg.inv(np.stack([pts[c0[1]] - origin, pts[c0[3]] - origin, pts[c0[4]] - origin], axis=1))
    g_pts = (pts - origin) @ to_grid.T
    n = int(round(g_pts.max()))
    lo = np.minimum.reduceat(g_pts[conn], offs[:-1], axis=0)
    hi = np.maximum.reduceat(g_pts[conn], offs[:-1], axis=0)

    rng = np.random.default_rng(a.seed)
    q = rng.uniform(pts.min(axis=0), pts.max(axis=0), size=(count(a.points), 3))
    g = (q - origin) @ to_grid.T
    inside = np.all((g > 0) & (g < n), axis=1)

    def wrong(ids: np.ndarray) -> int:
        found = ids >= 0
        c = ids[found]
        bad = np.any((g[found] < lo[c] - 1e-9) | (g[found] > hi[c] + 1e-9), axis=1)
        return int(bad.sum() + (inside & ~found).sum())

    # VTK: probe a cell-id array.
    grid.GetCellData().AddArray(numpy_to_vtk(np.arange(n_cells, dtype=np.float64), deep=1, array_type=vtk.VTK_DOUBLE))
    grid.GetCellData().GetArray(grid.GetCellData().GetNumberOfArrays() - 1).SetName("cid")
    poly = vtk.vtkPolyData()
    vp = vtk.vtkPoints()
    vp.SetData(numpy_to_vtk(q, deep=1))
    poly.SetPoints(vp)
    probe = vtk.vtkProbeFilter()
    probe.SetSourceData(grid)
    probe.SetInputData(poly)
    if hasattr(probe, "SetCellLocator"):
        probe.SetCellLocator(vtk.vtkStaticCellLocator())
    else:
        probe.SetCellLocatorPrototype(vtk.vtkStaticCellLocator())
    t = time.perf_counter()
    probe.Update()
    t_vtk = time.perf_counter() - t
    out = probe.GetOutput().GetPointData()
    mask = vtk_to_numpy(out.GetArray("vtkValidPointMask")).astype(bool)
    vtk_ids = np.where(mask, vtk_to_numpy(out.GetArray("cid")), -1).astype(np.int64)

    t = time.perf_counter()
    mesh = tetloc.read(a.mesh)
    t_read = time.perf_counter() - t
    t = time.perf_counter()
    loc = tetloc.Locator(mesh, backend="cpu")
    t_build = time.perf_counter() - t
    t = time.perf_counter()
    ids = np.asarray(loc.locate(q)).astype(np.int64)
    t_locate = time.perf_counter() - t

    print(f"mesh {a.mesh}: {n_cells} cells ({n}^3 grid), {len(q)} points, {int(inside.sum())} inside")
    print(f"VTK vtkProbeFilter+vtkStaticCellLocator: {t_vtk:.2f} s (locator build included), wrong {wrong(vtk_ids)}")
    print(
        f"tetloc cpu: build {t_build:.2f} s + locate {t_locate:.2f} s = {t_build + t_locate:.2f} s "
        f"(read {t_read:.2f} s, not counted), wrong {wrong(ids)}"
    )
    print(f"ratio VTK / tetloc (build + locate): {t_vtk / (t_build + t_locate):.2f}")


if __name__ == "__main__":
    main()
