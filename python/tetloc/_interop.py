"""pyvista and meshio in and out. Each is imported only when its conversion is used.

Cells follow the readers' rules: every volume cell tetloc reads is kept with all its nodes
(tets, hexahedra, wedges, pyramids, their higher-order kinds, mixed), 0-2-D cells (vertices,
lines, surfaces) are ignored with their cell data, and any other volume cell refuses the mesh
with a count by type. Both ways go through VTK cell lists (``_cells``), the form the core
takes and gives.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Dict, Tuple

import numpy as np

from . import _cells

if TYPE_CHECKING:
    from ._mesh import Mesh

Arrays = Tuple[np.ndarray, _cells.CellList, Dict[str, np.ndarray], Dict[str, np.ndarray]]


def _numeric(data: Any, keep: Any = None) -> Dict[str, np.ndarray]:
    """The numeric arrays of a data dict (restricted to rows `keep`); others are skipped."""
    out = {}
    for name, values in data.items():
        a = np.asarray(values)
        if a.dtype.kind not in "biuf":
            continue  # strings, objects: not a field
        out[str(name)] = a if keep is None else a[keep]
    return out


def _volume(cells: _cells.CellList, source: str, names: Any) -> Tuple[_cells.CellList, Any]:
    """The volume cells of a cell list (0-2-D cells dropped; voxels as hexahedra), and which
    cells they were (None: all)."""
    types = cells[0]
    lower = np.isin(types, _cells.LOWER)
    keep = None
    if lower.any():
        keep = ~lower
        cells = _cells.select(cells, keep)
    cells = _cells.voxels_as_hexahedra(cells)
    _cells.check_types(cells[0], cells[1], source, names)
    if len(cells[0]) == 0:
        raise ValueError(f"{source}: the mesh has no volume cells")
    return cells, keep


def from_pyvista(grid: Any) -> Arrays:
    import pyvista as pv

    if not isinstance(grid, pv.DataSet):
        raise TypeError(f"grid: expected a pyvista dataset, got {type(grid).__name__}")
    if not isinstance(grid, pv.UnstructuredGrid):
        grid = grid.cast_to_unstructured_grid()
    from vtkmodules.util.numpy_support import vtk_to_numpy

    vtk_cells = grid.GetCells()  # VTK 9's offsets + connectivity (pyvista's names for them vary)
    offsets = vtk_to_numpy(vtk_cells.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(vtk_cells.GetConnectivityArray()).astype(np.int64)
    types = np.asarray(grid.celltypes).astype(np.uint8)

    def name(code: int) -> str:
        try:
            return pv.CellType(code).name.lower()
        except ValueError:
            return f"VTK type {code}"

    cells, keep = _volume((types, offsets, conn), "pyvista grid", name)
    return np.asarray(grid.points), cells, _numeric(grid.point_data), _numeric(grid.cell_data, keep)


def to_pyvista(mesh: "Mesh") -> Any:
    import pyvista as pv

    # The file's coordinates: float64 where float32 would round them (a mesh far from the origin).
    points, points64 = mesh.points, mesh.points64
    exact32 = np.array_equal(points.astype(np.float64), points64)
    cells = mesh._cell_list()
    grid = pv.UnstructuredGrid(_cells.to_padded(cells), cells[0], points if exact32 else points64)
    for name in mesh.point_data:
        grid.point_data[name] = mesh.field(name)
    for name in mesh.cell_data:
        grid.cell_data[name] = mesh.field(name)
    return grid


def from_meshio(m: Any) -> Arrays:
    from meshio._vtk_common import meshio_to_vtk_order, meshio_to_vtk_type
    from meshio.gmsh.common import _meshio_to_gmsh_type

    from ._tetloc import gmsh_cell_type

    source = "meshio mesh"
    points = np.asarray(m.points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{source}: points of shape {points.shape}; expected (N, 3)")
    types, sizes, conn, skipped = [], [], [], set()
    unknown: Dict[str, int] = {}
    for i, block in enumerate(m.cells):
        data = np.asarray(block.data)
        code = meshio_to_vtk_type.get(block.type)
        order = meshio_to_vtk_order(block.type)  # meshio's linear wedge is Gmsh's, not VTK's
        if code is None:
            # Gmsh's higher orders (tetra20, hexahedron64, ...) keep Gmsh's node order in meshio.
            gmsh = gmsh_cell_type(_meshio_to_gmsh_type.get(block.type, 0))
            if gmsh is None or data.ndim != 2 or data.shape[1] != gmsh[1]:
                if block.type.startswith(("vertex", "line", "triangle", "quad", "polygon")):
                    skipped.add(i)  # a 0-2-D block of an order VTK does not name: ignored too
                else:
                    unknown[block.type] = unknown.get(block.type, 0) + len(data)
                continue
            code, _, order = gmsh
        if order is not None:
            data = data[:, order]
        types.append(np.full(len(data), code, np.uint8))
        sizes.append(np.full(len(data), data.shape[1] if data.ndim == 2 else 0, np.int64))
        conn.append(data.reshape(-1).astype(np.int64))
    if unknown:
        listed = ", ".join(f"{n} {t}" for t, n in sorted(unknown.items()))
        raise ValueError(f"{source}: the mesh has cells that tetloc does not read ({listed})")
    if not types:
        raise ValueError(f"{source}: the mesh has no volume cells")
    offsets = np.concatenate([[0], np.cumsum(np.concatenate(sizes))]).astype(np.int64)
    all_types = np.concatenate(types)
    vtk_names = {code: name for name, code in meshio_to_vtk_type.items()}
    cells, keep = _volume(
        (all_types, offsets, np.concatenate(conn)), source, lambda c: vtk_names.get(c, f"VTK type {c}")
    )
    cell_data = {}
    for name, per_block in m.cell_data.items():
        parts = [np.asarray(p) for i, p in enumerate(per_block) if i not in skipped]
        if all(p.dtype.kind in "biuf" for p in parts):
            values = np.concatenate(parts)
            cell_data[name] = values if keep is None else values[keep]
    return points, cells, _numeric(m.point_data), cell_data


def to_meshio(mesh: "Mesh") -> Any:
    import meshio
    from meshio._vtk_common import vtk_to_meshio_order, vtk_to_meshio_type

    types, offsets, conn = mesh._cell_list()
    blocks, spans = [], _cells.runs(types, offsets)
    for start, end in spans:
        code, k = int(types[start]), int(offsets[start + 1] - offsets[start])
        rows = conn[offsets[start]:offsets[end]].reshape(-1, k)
        order = vtk_to_meshio_order(code)
        blocks.append((vtk_to_meshio_type[code], rows if order is None else rows[:, order]))
    points, points64 = mesh.points, mesh.points64
    exact32 = np.array_equal(points.astype(np.float64), points64)
    point_data = {name: mesh.field(name) for name in mesh.point_data}
    cell_data = {}
    for name in mesh.cell_data:
        values = mesh.field(name)
        cell_data[name] = [values[a:b] for a, b in spans]
    return meshio.Mesh(
        points if exact32 else points64,
        [_meshio_block(meshio, t, rows) for t, rows in blocks],
        point_data=point_data,
        cell_data=cell_data,
    )


def _meshio_block(meshio: Any, cell_type: str, rows: np.ndarray) -> Any:
    """A meshio cell block. meshio names some VTK volume types (wedge15, pyramid13, Bezier
    tets) without listing their dimension, and then cannot make a block of them: one is
    made with the dimension given (its writers need no more)."""
    try:
        return meshio.CellBlock(cell_type, rows)
    except KeyError:
        block = meshio.CellBlock.__new__(meshio.CellBlock)
        block.type, block.data, block.dim, block.tags = cell_type, rows, 3, []
        return block
