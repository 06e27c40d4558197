"""``tetloc.Mesh`` and ``tetloc.read``."""

from __future__ import annotations

import errno
import json
import os
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _cells, _fields, _interop
from ._tetloc import _Mesh, read_mesh

ArrayLike = npt.ArrayLike
Ids = npt.NDArray[np.int64]


class Mesh:
    """An unstructured volume mesh with named fields, ready for point location: tetrahedra,
    hexahedra, wedges and pyramids, their higher-order kinds (quadratic, Lagrange, Bezier
    tets), or any mix of them. Points are located in tets: a mesh of tets as it is, other
    cells through their conforming tet decomposition (``tets``), answered as the cells.

    Parameters
    ----------
    points : array-like, shape (N, 3)
        Vertex coordinates, float32 or float64 (float64 ones are kept where float32 would round
        them, as for meshes read from files).
    cells : array-like
        The cells, in one of pyvista's forms:

        - an (M, 4) integer array: linear tetrahedra, one row each;
        - a dict ``{VTK cell type: (n, k) ids}`` (``pyvista.CellType`` keys, as
          ``pyvista.UnstructuredGrid({CellType.HEXAHEDRON: ...}, points)`` takes), cells in
          the dict's order;
        - with `celltypes`, pyvista's flat array ``[n0, ids..., n1, ids...]`` (as
          ``pyvista.UnstructuredGrid(cells, celltypes, points)`` takes).

        Ids are 0-based vertex ids in VTK's node order for each type. Inverted tets are
        reoriented and kept; cell ids are the cells' order.
    point_data, cell_data : dict of name -> array, optional
        Fields: (N,) or (N, k) per point, (M,) or (M, k) per cell (one row per cell, not per
        tet). Stored as float32 (float64 data keeps its values).
    celltypes : array-like, shape (M,), optional
        VTK cell type codes of the cells of a flat `cells` array.

    Raises ``ValueError`` naming the argument and the problem (shapes, dtypes, ids out of
    range, non-finite coordinates, cell types tetloc does not read).
    """

    _raw: _Mesh

    def __init__(
        self,
        points: ArrayLike,
        cells: Union[ArrayLike, Mapping[Any, ArrayLike]],
        point_data: Optional[Mapping[str, ArrayLike]] = None,
        cell_data: Optional[Mapping[str, ArrayLike]] = None,
        celltypes: Optional[ArrayLike] = None,
    ) -> None:
        source = "tetloc.Mesh(points, cells)"
        if isinstance(cells, Mapping):
            self._build(points, None, _cells.from_blocks(cells), point_data, cell_data, source)
        elif celltypes is not None:
            self._build(points, None, _cells.from_padded(cells, celltypes), point_data, cell_data, source)
        else:
            self._build(points, cells, None, point_data, cell_data, source)

    @classmethod
    def _from_cell_list(
        cls,
        points: ArrayLike,
        cell_list: _cells.CellList,
        point_data: Optional[Mapping[str, ArrayLike]],
        cell_data: Optional[Mapping[str, ArrayLike]],
        source: str,
    ) -> "Mesh":
        mesh = cls.__new__(cls)
        mesh._build(points, None, cell_list, point_data, cell_data, source)
        return mesh

    def _build(
        self,
        points: ArrayLike,
        tets: Optional[ArrayLike],
        cell_list: Optional[_cells.CellList],
        point_data: Optional[Mapping[str, ArrayLike]],
        cell_data: Optional[Mapping[str, ArrayLike]],
        source: str,
    ) -> None:
        """Checks the arrays and builds the core mesh: (M, 4) `tets`, or a VTK `cell_list`."""
        pts = np.asarray(points)
        if pts.dtype.kind not in "iuf" or pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points: shape {pts.shape}, dtype {pts.dtype}; expected (N, 3) float32 or float64")
        if cell_list is None:
            tets = np.asarray(tets)
            if tets.dtype.kind not in "iu" or tets.ndim != 2 or tets.shape[1] != 4:
                raise ValueError(
                    f"cells: shape {tets.shape}, dtype {tets.dtype}; expected (M, 4) integer vertex ids of tets "
                    "(other cells: a dict {celltype: ids}, or pyvista's flat cells with celltypes)"
                )
            if tets.size and (tets.min() < 0 or tets.max() >= len(pts)):
                bad = int(np.argmax(((tets < 0) | (tets >= len(pts))).any(axis=1)))
                raise ValueError(f"cells: row {bad} {tets[bad].tolist()} names a vertex outside 0..{len(pts) - 1}")
            n_cells = len(tets)
        else:
            types, offsets, conn = cell_list
            _cells.check_types(types, offsets, source)
            if conn.size and (conn.min() < 0 or conn.max() >= len(pts)):
                k = int(np.argmax((conn < 0) | (conn >= len(pts))))
                bad = int(np.searchsorted(offsets, k, side="right")) - 1
                raise ValueError(
                    f"cells: cell {bad} {conn[offsets[bad]:offsets[bad + 1]].tolist()} names a vertex outside "
                    f"0..{len(pts) - 1}"
                )
            n_cells = len(types)
        fields = _fields.split(point_data, "point", len(pts), "point_data") + _fields.split(
            cell_data, "cell", n_cells, "cell_data"
        )
        names = [name for name, _, _ in fields]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"point_data/cell_data: field names given twice: {dup} (vector NAME gives NAME[i])")
        # float64 coordinates are kept where float32 would round them: answers are then
        # exact on them (and a mesh far from the origin keeps its precision).
        wide = pts.dtype.kind == "f" and pts.dtype.itemsize == 8  # big-endian '>f8' too
        points64 = np.ascontiguousarray(pts, dtype=np.float64) if wide else None
        points32 = np.ascontiguousarray(pts, dtype=np.float32)
        if cell_list is None:
            conn32 = np.ascontiguousarray(tets, dtype=np.uint32).ravel()
            self._raw = _Mesh(points32, conn32, fields, source, points64)
        else:
            self._raw = _Mesh(
                points32,
                np.ascontiguousarray(conn, dtype=np.uint32),
                fields,
                source,
                points64,
                np.ascontiguousarray(types, dtype=np.uint8),
                np.ascontiguousarray(offsets, dtype=np.int64),
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
        """The volume cells of a ``pyvista.UnstructuredGrid`` (or any pyvista dataset: images
        and structured grids as hexahedra), with its point and cell data. Every cell type
        tetloc reads is taken (tets, hexahedra, wedges, pyramids, their higher-order kinds,
        mixed); 0-2-D cells (vertices, lines, surfaces) are ignored with their cell data; other
        volume cells (polyhedra, prisms, ...) raise ``ValueError`` with a count by type."""
        points, cell_list, point_data, cell_data = _interop.from_pyvista(grid)
        return cls._from_cell_list(points, cell_list, point_data, cell_data, "pyvista grid")

    def to_pyvista(self) -> Any:
        """A ``pyvista.UnstructuredGrid`` of the cells (``cells``, ``celltypes``) with every
        field as point or cell data."""
        return _interop.to_pyvista(self)

    @classmethod
    def from_meshio(cls, mesh: Any) -> "Mesh":
        """The volume cells of a ``meshio.Mesh`` (every type tetloc reads: ``tetra``,
        ``tetra10``, ``hexahedron``, ``hexahedron27``, ``wedge``, ``pyramid13``, Lagrange
        blocks, ...), in block order, with its point data and the cell data of those blocks;
        0-2-D blocks are ignored."""
        points, cell_list, point_data, cell_data = _interop.from_meshio(mesh)
        return cls._from_cell_list(points, cell_list, point_data, cell_data, "meshio mesh")

    def to_meshio(self) -> Any:
        """A ``meshio.Mesh``: one cell block per run of cells of one type, with every field as
        point data or as cell data (split by block)."""
        return _interop.to_meshio(self)

    # Properties.

    @property
    def n_points(self) -> int:
        """Number of vertices."""
        return self._raw.n_points

    @property
    def n_cells(self) -> int:
        """Number of cells (of every type; not their tet decomposition: ``n_tets``)."""
        return self._raw.n_cells

    @property
    def n_tets(self) -> int:
        """Number of tets located in: ``n_cells`` for a mesh of tets, the decomposition's
        count for other cells (1 a tet, 2 or 3 a pyramid, 3 a wedge, 5 or 6 a hexahedron)."""
        return self._raw.n_tets

    @property
    def bounds(self) -> Tuple[float, float, float, float, float, float]:
        """(xmin, xmax, ymin, ymax, zmin, zmax) of the vertices that cells use (pyvista's order)."""
        lo, hi = self._raw.bounds
        return (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])

    @property
    def point_data(self) -> Dict[str, Tuple[int, ...]]:
        """Per-point fields: name -> shape, (N,) or (N, k)."""
        return self._index.shapes("point", self.n_points)

    @property
    def cell_data(self) -> Dict[str, Tuple[int, ...]]:
        """Per-cell fields: name -> shape, (M,) or (M, k), one row per cell."""
        return self._index.shapes("cell", self.n_cells)

    @property
    def points(self) -> npt.NDArray[np.float32]:
        """A copy of the vertices, (N, 3) float32."""
        return self._raw.points()

    @property
    def points64(self) -> npt.NDArray[np.float64]:
        """A copy of the vertices at the precision the file (or the arrays given) has them,
        (N, 3) float64: what exact answers are decided on."""
        return self._raw.points64()

    # The cells, as pyvista's UnstructuredGrid names them.

    def _cell_list(self) -> _cells.CellList:
        return self._raw.cell_list()

    @property
    def celltypes(self) -> npt.NDArray[np.uint8]:
        """VTK cell type code of each cell, (M,) uint8 (``pyvista.CellType``: 10 a tet, 12 a
        hexahedron, 13 a wedge, 14 a pyramid, 24 a quadratic tet, ...)."""
        return self._cell_list()[0]

    @property
    def offsets(self) -> Ids:
        """(M + 1,) int64: cell ``i``'s vertex ids are ``cell_connectivity[offsets[i]:offsets[i + 1]]``."""
        return self._cell_list()[1]

    @property
    def cell_connectivity(self) -> Ids:
        """Every cell's vertex ids, one cell after the other, int64, VTK's node order."""
        return self._cell_list()[2]

    @property
    def cells(self) -> Ids:
        """The cells as pyvista's ``UnstructuredGrid.cells`` has them: a flat int64 array
        ``[n0, ids..., n1, ids...]`` (with ``celltypes``, what
        ``pyvista.UnstructuredGrid(cells, celltypes, points)`` takes). The cells are the
        input's, in its order, with all their nodes; tets (and higher-order tets' corners,
        their other nodes following them) in tetloc's canonical right-handed order. For
        (M, k) blocks per type: ``cells_dict``; for the tets located in: ``tets``."""
        return _cells.to_padded(self._cell_list())

    @property
    def cells_dict(self) -> Dict[int, Ids]:
        """``{VTK cell type: (n, k) int64 ids}``, as pyvista's ``cells_dict``
        (``mesh.cells_dict[10]``: the (M, 4) tets of a mesh of linear tets)."""
        return _cells.to_blocks(self._cell_list())

    @property
    def tets(self) -> Ids:
        """The tets located in, (T, 4) int64, each in tetloc's canonical right-handed (VTK)
        order: a mesh of tets's own (the corners of higher-order ones), in cell order; for
        other cells their conforming decomposition, each cell's tets together
        (``tet_cells`` maps them to their cells)."""
        return self._raw.tets()

    @property
    def tet_cells(self) -> Ids:
        """The cell each of ``tets`` is or belongs to, (T,) int64."""
        return self._raw.tet_cells()

    @property
    def times(self) -> List[float]:
        """The time of each step of a time series (an Exodus file with steps, a ``.pvd``
        collection), ascending; empty for a single snapshot. The mesh's fields are the first
        step's; ``field(name, step=k)`` reads step k's."""
        return list(self._raw.times)

    def field(self, name: str, step: Optional[int] = None) -> npt.NDArray[np.floating[Any]]:
        """A copy of field `name`'s values, (N,) or (N, k): float64 where the file stored
        them in f64 (and they do not all round to f32 exactly), else float32. With `step`
        (0-based, an index into ``times``), that time step's values, read from the file now
        (one step at a time: memory holds no other step); ``ValueError`` for a step out of
        range or a mesh without steps."""
        comps, k = self._index.components(name)
        if step is None:
            return _fields.join([self._raw.field(c) for c in comps], k)
        step = _step_index(step)
        return _fields.join(self._raw.step_fields(list(comps), step), k)

    def at_step(self, step: int) -> "Mesh":
        """This mesh with the fields of time step `step` (0-based, an index into ``times``) in
        place of the first step's, so that ``probe``, ``resample_to_image``, ``trace`` and
        ``Locator`` work on that step (as the CLI's ``--time-step K``): only that step's fields
        are read, on this mesh's geometry (shared, not copied), its steps kept. ``ValueError``
        for a step out of range or a mesh without steps. To sample many steps at the same
        points, locate once instead: ``Locator.step_weights``."""
        return Mesh._wrap(self._raw.at_step(_step_index(step)))

    def field_location(self, name: str) -> str:
        """Where field `name` lives: "point" or "cell"."""
        self._index.components(name)
        return self._index.fields[name][0]

    def info(self) -> Dict[str, Any]:
        """What ``tetloc info --json`` prints: counts (cells by type, tets), bounds, edge
        lengths, volume, reoriented/degenerate cells, shared faces, fields."""
        info: Dict[str, Any] = json.loads(self._raw.info_json())
        return info

    def __repr__(self) -> str:
        def names(d: Dict[str, Tuple[int, ...]]) -> str:
            return ", ".join(n if len(s) == 1 else f"{n}{list(s[1:])}" for n, s in d.items()) or "none"

        cells = _cells.counts_text(self._raw.cell_type_counts(), self.n_cells, self.n_tets)
        return (
            f"tetloc.Mesh({cells}, {self.n_points} points; point data: {names(self.point_data)}; "
            f"cell data: {names(self.cell_data)}; from {self._raw.source})"
        )


def _step_index(step: Any) -> int:
    """A time step argument as an index (a bool or a float is a ``TypeError``)."""
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)):
        raise TypeError(f"step: expected an int (an index into Mesh.times), got {type(step).__name__}")
    if step < 0:
        raise ValueError(f"step: {step} is negative; steps are 0-based indices into Mesh.times")
    return int(step)


def _is_openfoam_case(folder: str) -> bool:
    """Whether `folder` is an OpenFOAM case: a reconstructed or a decomposed mesh."""
    return any(os.path.isdir(os.path.join(folder, *p, "constant", "polyMesh")) for p in [(), ("processor0",)])


def read(
    path: Union[str, "os.PathLike[str]"], format: Optional[str] = None, *, allow_outside_pieces: bool = False
) -> Mesh:
    """Reads a mesh in any format the ``tetloc`` CLI reads, by extension or `format`: VTK XML
    ``.vtu``, its parallel pieces ``.pvtu`` and multiblock ``.vtm`` ("vtu", "pvtu", "vtm"),
    legacy ``.vtk`` ("vtk"), Gmsh ``.msh`` 2.2 and 4.1 ("msh"), TetGen ``.node``/``.ele``
    ("node"), and time series: Exodus II ``.e``/``.exo``/``.ex2`` ("exo"), ParaView's
    ``.pvd`` collections ("pvd") and OpenFOAM cases (their ``NAME.foam`` file or folder,
    "foam"; "foam-decomposed" reads the ``processor*/`` folders of a case that also has a
    reconstructed mesh), whose steps ``Mesh.times`` lists. Every volume cell tetloc reads is
    taken: tets, hexahedra, wedges, pyramids, their higher-order kinds, polyhedra, and mixes of
    them; 0-2-D cells are ignored.

    A ``.pvtu``/``.vtm`` may list pieces only inside its own folder tree: pieces reached by
    ``../``, an absolute path or a symbolic link out of it raise ``ValueError`` (a listing
    from an untrusted source should not read arbitrary files), unless
    ``allow_outside_pieces=True`` (the CLI's ``--allow-outside-pieces``).

    Raises ``FileNotFoundError``, ``IsADirectoryError`` (and other ``OSError``) when the file
    cannot be opened, ``ValueError`` naming the file and the problem when it cannot be used
    (malformed, cells of a type tetloc does not read such as pentagonal prisms, ...). Interruptible
    with Ctrl-C.
    """
    path = os.fspath(path)
    if os.path.isdir(path) and not _is_openfoam_case(path):
        raise IsADirectoryError(
            errno.EISDIR,
            "is a directory and not an OpenFOAM case; tetloc.read takes a mesh file (.vtu, .pvtu, .vtm, .vtk, .msh, "
            ".node, .foam) or an OpenFOAM case folder",
            path,
        )
    return Mesh._wrap(read_mesh(path, format, allow_outside_pieces))
