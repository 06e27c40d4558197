"""``tetloc.Mesh`` and ``tetloc.read``."""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Mapping, Optional, Tuple, Union

import numpy as np

from . import _fields, _interop
from ._tetloc import _Mesh, read_mesh

ArrayLike = Any


class Mesh:
    """A tetrahedral mesh with named fields, ready for point location.

    Parameters
    ----------
    points : array-like, shape (N, 3)
        Vertex coordinates, float32 or float64 (float64 ones are kept where float32 would round
        them, as for meshes read from files).
    cells : array-like, shape (M, 4)
        Vertex ids of each tetrahedron, any integer dtype. Inverted tets are reoriented
        and kept; cell ids are the rows' order.
    point_data, cell_data : dict of name -> array, optional
        Fields: (N,) or (N, k) per point, (M,) or (M, k) per cell. Stored as float32.

    Raises ``ValueError`` naming the argument and the problem (shapes, dtypes, ids out of
    range, non-finite coordinates).
    """

    _raw: _Mesh

    def __init__(
        self,
        points: ArrayLike,
        cells: ArrayLike,
        point_data: Optional[Mapping[str, ArrayLike]] = None,
        cell_data: Optional[Mapping[str, ArrayLike]] = None,
    ) -> None:
        pts = np.asarray(points)
        if pts.dtype.kind not in "iuf" or pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points: shape {pts.shape}, dtype {pts.dtype}; expected (N, 3) float32 or float64")
        cells_ = np.asarray(cells)
        if cells_.dtype.kind not in "iu" or cells_.ndim != 2 or cells_.shape[1] != 4:
            raise ValueError(f"cells: shape {cells_.shape}, dtype {cells_.dtype}; expected (M, 4) integer vertex ids")
        if cells_.size and (cells_.min() < 0 or cells_.max() >= len(pts)):
            bad = int(np.argmax(((cells_ < 0) | (cells_ >= len(pts))).any(axis=1)))
            raise ValueError(
                f"cells: row {bad} {cells_[bad].tolist()} names a vertex outside 0..{len(pts) - 1}"
            )
        fields = _fields.split(point_data, "point", len(pts), "point_data") + _fields.split(
            cell_data, "cell", len(cells_), "cell_data"
        )
        names = [name for name, _, _ in fields]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"point_data/cell_data: field names given twice: {dup} (vector NAME gives NAME[i])")
        self._raw = _Mesh(
            np.ascontiguousarray(pts, dtype=np.float32),
            np.ascontiguousarray(cells_, dtype=np.uint32),
            fields,
            "tetloc.Mesh(points, cells)",
            # float64 coordinates are kept where float32 would round them: answers are then
            # exact on them (and a mesh far from the origin keeps its precision).
            np.ascontiguousarray(pts, dtype=np.float64) if pts.dtype == np.float64 else None,
        )
        self._index = _fields.FieldIndex(self._raw.fields())

    @classmethod
    def _wrap(cls, raw: _Mesh) -> "Mesh":
        mesh = cls.__new__(cls)
        mesh._raw = raw
        mesh._index = _fields.FieldIndex(raw.fields())
        return mesh

    # Conversions (pyvista and meshio are imported only here).

    @classmethod
    def from_pyvista(cls, grid: Any) -> "Mesh":
        """The tetrahedra of a ``pyvista.UnstructuredGrid`` (or any pyvista dataset), with its
        point and cell data. Higher-order tets keep their corners; 0-2-D cells are ignored;
        other volume cells are refused (``ValueError`` with a count by type)."""
        points, cells, point_data, cell_data = _interop.from_pyvista(grid)
        return cls(points, cells, point_data, cell_data)

    def to_pyvista(self) -> Any:
        """A ``pyvista.UnstructuredGrid`` of the tets with every field as point or cell data."""
        return _interop.to_pyvista(self)

    @classmethod
    def from_meshio(cls, mesh: Any) -> "Mesh":
        """The tetrahedra of a ``meshio.Mesh`` (``tetra``, and the corners of ``tetra10`` etc.)
        with its point data and the cell data of those blocks."""
        points, cells, point_data, cell_data = _interop.from_meshio(mesh)
        return cls(points, cells, point_data, cell_data)

    # Properties.

    @property
    def n_points(self) -> int:
        """Number of vertices."""
        return self._raw.n_points

    @property
    def n_cells(self) -> int:
        """Number of tetrahedra."""
        return self._raw.n_cells

    @property
    def bounds(self) -> Tuple[float, float, float, float, float, float]:
        """(xmin, xmax, ymin, ymax, zmin, zmax) of the vertices that tets use (pyvista's order)."""
        lo, hi = self._raw.bounds
        return (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])

    @property
    def point_data(self) -> Dict[str, Tuple[int, ...]]:
        """Per-point fields: name -> shape, (N,) or (N, k)."""
        return self._index.shapes("point", self.n_points)

    @property
    def cell_data(self) -> Dict[str, Tuple[int, ...]]:
        """Per-cell fields: name -> shape, (M,) or (M, k)."""
        return self._index.shapes("cell", self.n_cells)

    @property
    def points(self) -> np.ndarray:
        """A copy of the vertices, (N, 3) float32."""
        return self._raw.points()

    @property
    def points64(self) -> np.ndarray:
        """A copy of the vertices at the precision the file (or the arrays given) has them,
        (N, 3) float64: what exact answers are decided on."""
        return self._raw.points64()

    @property
    def cells(self) -> np.ndarray:
        """A copy of the tets, (M, 4) int64, in the input's order; each tet's vertices in
        tetloc's canonical (right-handed, VTK) order."""
        return self._raw.cells()

    def field(self, name: str) -> np.ndarray:
        """A copy of field `name`'s values, (N,) or (N, k): float64 where the file stored
        them in f64 (and they do not all round to f32 exactly), else float32."""
        comps, k = self._index.components(name)
        return _fields.join([self._raw.field(c) for c in comps], k)

    def info(self) -> Dict[str, Any]:
        """What ``tetloc info --json`` prints: counts, bounds, edge lengths, volume,
        reoriented/degenerate tets, shared faces, fields."""
        return json.loads(self._raw.info_json())

    def __repr__(self) -> str:
        def names(d: Dict[str, Tuple[int, ...]]) -> str:
            return ", ".join(n if len(s) == 1 else f"{n}{list(s[1:])}" for n, s in d.items()) or "none"

        return (
            f"tetloc.Mesh({self.n_cells} tets, {self.n_points} points; point data: {names(self.point_data)}; "
            f"cell data: {names(self.cell_data)}; from {self._raw.source})"
        )


def read(path: Union[str, "os.PathLike[str]"], format: Optional[str] = None) -> Mesh:
    """Reads a mesh in any format the ``tetloc`` CLI reads: VTK XML ``.vtu``, legacy
    ``.vtk``, Gmsh ``.msh`` (2.2, 4.1), TetGen ``.node``/``.ele``; by extension, or
    `format` ("vtu", "vtk", "msh", "node").

    Raises ``FileNotFoundError`` (and other ``OSError``) when the file cannot be opened,
    ``ValueError`` naming the file and the problem when it cannot be used (malformed,
    cells that are not tetrahedra, ...). Interruptible with Ctrl-C.
    """
    return Mesh._wrap(read_mesh(os.fspath(path), format))
