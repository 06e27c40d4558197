"""pyvista and meshio in and out. Each is imported only when its conversion is used.

Cells follow the readers' rules: linear tets are kept, higher-order tets keep their 4
corner vertices, 0-2-D cells (vertices, lines, surfaces) are ignored, and any other volume
cell refuses the mesh with a count by type.
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, Any, Dict, Tuple

import numpy as np

if TYPE_CHECKING:
    from ._mesh import Mesh

Arrays = Tuple[np.ndarray, np.ndarray, Dict[str, np.ndarray], Dict[str, np.ndarray]]

# VTK cell type codes (vtkCellType.h): tets, higher-order tets with their corners first
# (quadratic, Lagrange, Bezier), and the cells of dimension 0-2.
_VTK_TET = 10
_VTK_HIGHER_TETS = (24, 71, 78)
_VTK_LOWER = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 21, 22, 23, 28, 30, 34, 35, 36, 51, 52, 53, 54, 60, 61, 62, 63,
              68, 69, 70, 75, 76, 77)


def _refuse(source: str, counts: Counter) -> None:
    listed = ", ".join(f"{n} {name}" for name, n in sorted(counts.items()))
    raise ValueError(
        f"{source}: the mesh has volume cells that are not tetrahedra ({listed}); "
        "tetloc locates points in tetrahedral meshes only"
    )


def _numeric(data: Any, keep: Any = None) -> Dict[str, np.ndarray]:
    """The numeric arrays of a data dict (restricted to rows `keep`); others are skipped."""
    out = {}
    for name, values in data.items():
        a = np.asarray(values)
        if a.dtype.kind not in "biuf":
            continue  # strings, objects: not a field
        out[str(name)] = a if keep is None else a[keep]
    return out


def from_pyvista(grid: Any) -> Arrays:
    import pyvista as pv

    if not isinstance(grid, pv.DataSet):
        raise ValueError(f"grid: expected a pyvista dataset, got {type(grid).__name__}")
    if not isinstance(grid, pv.UnstructuredGrid):
        grid = grid.cast_to_unstructured_grid()
    source = "pyvista grid"
    types = np.asarray(grid.celltypes)
    from vtkmodules.util.numpy_support import vtk_to_numpy

    vtk_cells = grid.GetCells()  # VTK 9's offsets + connectivity (pyvista's names for them vary)
    offsets = vtk_to_numpy(vtk_cells.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(vtk_cells.GetConnectivityArray()).astype(np.int64)
    is_tet = (types == _VTK_TET) | np.isin(types, _VTK_HIGHER_TETS)
    other = ~is_tet & ~np.isin(types, _VTK_LOWER)
    if other.any():
        _refuse(source, Counter(pv.CellType(t).name.lower() for t in types[other]))
    sizes = np.diff(offsets)[is_tet]
    if (sizes < 4).any():
        raise ValueError(f"{source}: a tetrahedron with {int(sizes.min())} points")
    starts = offsets[:-1][is_tet]
    cells = conn[starts[:, None] + np.arange(4)]
    keep = None if is_tet.all() else is_tet
    point_data = _numeric(grid.point_data)
    cell_data = _numeric(grid.cell_data, keep)
    return np.asarray(grid.points), cells, point_data, cell_data


def to_pyvista(mesh: "Mesh") -> Any:
    import pyvista as pv

    # The file's coordinates: float64 where float32 would round them (a mesh far from the origin).
    points, points64 = mesh.points, mesh.points64
    exact32 = np.array_equal(points.astype(np.float64), points64)
    grid = pv.UnstructuredGrid({pv.CellType.TETRA: mesh.cells}, points if exact32 else points64)
    for name in mesh.point_data:
        grid.point_data[name] = mesh.field(name)
    for name in mesh.cell_data:
        grid.cell_data[name] = mesh.field(name)
    return grid


def from_meshio(m: Any) -> Arrays:
    source = "meshio mesh"
    points = np.asarray(m.points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{source}: points of shape {points.shape}; expected (N, 3)")
    lower = ("vertex", "line", "triangle", "quad", "polygon")
    blocks, others = [], Counter()
    for i, block in enumerate(m.cells):
        if block.type.startswith("tetra"):
            blocks.append(i)
        elif not block.type.startswith(lower):
            others[block.type] += len(block.data)
    if others:
        _refuse(source, others)
    if not blocks:
        raise ValueError(f"{source}: the mesh has no tetrahedra")
    cells = np.concatenate([np.asarray(m.cells[i].data)[:, :4] for i in blocks])
    cell_data = {}
    for name, per_block in m.cell_data.items():
        parts = [np.asarray(per_block[i]) for i in blocks]
        if all(p.dtype.kind in "biuf" for p in parts):
            cell_data[name] = np.concatenate(parts)
    return points, cells, _numeric(m.point_data), cell_data
