"""Cells as VTK cell lists: the one form every way in and out of a ``tetloc.Mesh`` shares.

A cell list is three arrays, pyvista's (``UnstructuredGrid.celltypes``, ``.offset`` and
``.cell_connectivity``): cell ``i`` is of VTK type ``types[i]`` (vtkCellType.h) with the points
``conn[offsets[i]:offsets[i + 1]]`` in VTK's node order. This module turns the other forms
(pyvista's padded ``cells`` array, a dict of blocks per type) into lists and back, and checks
cell types against those tetloc reads.
"""

from __future__ import annotations

from collections import Counter
from typing import Any, Dict, List, Mapping, Optional, Tuple

import numpy as np

from ._tetloc import vtk_cell_types

CellList = Tuple[np.ndarray, np.ndarray, np.ndarray]  # types uint8, offsets int64, connectivity int64

TETRA = 10
VOXEL = 11
HEXAHEDRON = 12
POLYHEDRON = 42
# A voxel is a hexahedron with its points in x-fastest order: VTK's hex order is this.
VOXEL_TO_HEX = np.array([0, 1, 3, 2, 4, 5, 7, 6])

# VTK cell type codes of dimension 0-2 (vertices, lines, surfaces): not part of a volume.
LOWER = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 21, 22, 23, 28, 30, 34, 35, 36, 51, 52, 53, 54, 60, 61, 62, 63,
         68, 69, 70, 75, 76, 77)


def readable() -> Dict[Tuple[int, int], str]:
    """(VTK code, point count) -> name of every volume cell type tetloc reads."""
    return {(code, n): name for code, n, name in vtk_cell_types()}


def sizes(offsets: np.ndarray) -> np.ndarray:
    return np.diff(offsets)


def check_types(types: np.ndarray, offsets: np.ndarray, source: str, names: Any = None) -> None:
    """Refuses cells of types tetloc does not read, counted by type (`names(code)` names a
    code; VTK's code otherwise)."""
    # Polyhedra are read from files (their faces are there), never from cell arrays.
    known = {k: name for k, name in readable().items() if k[0] != POLYHEDRON}
    keys, count_of = np.unique(types.astype(np.int64) << 32 | sizes(offsets), return_counts=True)
    bad: Counter[str] = Counter()
    polyhedra = False
    for key, count in zip(keys.tolist(), count_of.tolist()):
        code, n = key >> 32, key & 0xFFFFFFFF
        if (code, n) not in known:
            name = names(code) if names else f"VTK type {code}"
            polyhedra |= code == POLYHEDRON
            bad[f"{name} with {n} points" if code == POLYHEDRON or any(c == code for c, _ in known) else name] += count
    if bad:
        listed = ", ".join(f"{n} {name}" for name, n in sorted(bad.items()))
        kinds = sorted({name for name in known.values()})
        why = (
            "; polyhedra (VTK type 42) handed over as cell arrays carry no faces: tetloc reads them from "
            ".vtu and .vtk files and OpenFOAM cases (tetloc.read)"
            if polyhedra
            else ""
        )
        raise ValueError(
            f"{source}: the mesh has cells that tetloc does not read ({listed}){why}; "
            "it reads volume cells: " + ", ".join(kinds)
        )


def select(cells: CellList, keep: np.ndarray) -> CellList:
    """The cells where `keep` is true, in their order."""
    types, offsets, conn = cells
    n = sizes(offsets)[keep]
    starts = offsets[:-1][keep]
    new_offsets = np.concatenate([[0], np.cumsum(n)]).astype(np.int64)
    gather = np.repeat(starts - new_offsets[:-1], n) + np.arange(new_offsets[-1])
    return types[keep], new_offsets, conn[gather]


def voxels_as_hexahedra(cells: CellList) -> CellList:
    """Voxels (VTK type 11, what pyvista's images cast to) as the hexahedra they are."""
    types, offsets, conn = cells
    vox = (types == VOXEL) & (sizes(offsets) == 8)
    if not vox.any():
        return cells
    conn = conn.copy()
    rows = offsets[:-1][vox][:, None] + np.arange(8)
    conn[rows] = conn[rows][:, VOXEL_TO_HEX]
    types = np.where(vox, HEXAHEDRON, types).astype(np.uint8)
    return types, offsets, conn


def check_codes(codes: np.ndarray, arg: str) -> None:
    """VTK cell type codes are 0..255 (VTK's unsigned char): others are refused, not wrapped."""
    if codes.dtype.kind not in "iu" or not np.all((codes >= 0) & (codes <= 255)):
        bad = codes[~((codes >= 0) & (codes <= 255))][:3] if codes.dtype.kind in "iu" else codes[:3]
        raise ValueError(f"{arg}: VTK cell type codes are whole numbers from 0 to 255; got {list(bad)}")


def from_padded(cells: Any, celltypes: Any, arg: str = "cells") -> CellList:
    """pyvista's legacy padded array ``[n0, ids..., n1, ids...]`` with its cell types."""
    padded = np.asarray(cells)
    types = np.asarray(celltypes)
    if padded.ndim != 1 or padded.dtype.kind not in "iu":
        raise ValueError(f"{arg}: with celltypes, expected a flat integer array [n0, ids..., n1, ids...] (pyvista's cells)")
    if types.ndim != 1 or types.dtype.kind not in "iu":
        raise ValueError(f"celltypes: expected a 1-D array of VTK cell type codes, got shape {types.shape}, dtype {types.dtype}")
    check_codes(types, "celltypes")
    counts = np.empty(len(types), np.int64)
    k = int(padded[0]) if len(padded) else 0
    if len(padded) == len(types) * (k + 1) and (padded[:: k + 1] == k).all():
        counts[:] = k  # one point count for all: no walk
        pos = len(padded)
    else:
        pos = 0
    # One jump per cell: the counts interleave with the ids.
    for i in range(len(types) if pos == 0 else 0):
        if pos >= len(padded):
            raise ValueError(f"{arg}: {len(types)} celltypes but the array ends after {i} cells")
        counts[i] = padded[pos]
        pos += int(padded[pos]) + 1
    if pos != len(padded):
        raise ValueError(f"{arg}: {len(types)} celltypes but the array holds {len(padded) - pos} more entries")
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    ids = np.ones(len(padded), bool)
    ids[offsets[:-1] + np.arange(len(types))] = False
    return types.astype(np.uint8), offsets, padded[ids].astype(np.int64)


def to_padded(cells: CellList) -> np.ndarray:
    """pyvista's legacy padded array ``[n0, ids..., n1, ids...]``."""
    _, offsets, conn = cells
    m = len(offsets) - 1
    out = np.empty(len(conn) + m, np.int64)
    heads = offsets[:-1] + np.arange(m)  # where each cell's count goes
    out[heads] = sizes(offsets)
    ids = np.ones(len(out), bool)
    ids[heads] = False
    out[ids] = conn
    return out


def from_blocks(blocks: Mapping[Any, Any], arg: str = "cells") -> CellList:
    """A dict ``{VTK cell type: (n, k) ids}`` (pyvista's ``cells_dict``), blocks in the dict's order."""
    types, offsets, conn = [], [np.zeros(1, np.int64)], []
    end = 0
    for code, rows in blocks.items():
        check_codes(np.asarray([code]), f"{arg} (a key)")
        a = np.asarray(rows)
        if a.ndim != 2 or a.dtype.kind not in "iu":
            raise ValueError(f"{arg}[{int(code)}]: shape {a.shape}, dtype {a.dtype}; expected (n, k) integer ids")
        types.append(np.full(len(a), int(code), np.uint8))
        offsets.append(end + a.shape[1] * np.arange(1, len(a) + 1, dtype=np.int64))
        end += a.size
        conn.append(a.ravel().astype(np.int64))
    if not types:
        return np.zeros(0, np.uint8), np.zeros(1, np.int64), np.zeros(0, np.int64)
    return np.concatenate(types), np.concatenate(offsets), np.concatenate(conn)


def to_blocks(cells: CellList) -> Dict[int, np.ndarray]:
    """``{VTK cell type: (n, k) ids}``, as pyvista's ``cells_dict`` (one k per type)."""
    types, offsets, conn = cells
    out = {}
    for code in np.unique(types):
        sel = types == code
        k = sizes(offsets)[sel]
        if (k != k[0]).any():
            raise ValueError(f"cells of VTK type {int(code)} have {int(k.min())} to {int(k.max())} points: no (n, k) block")
        out[int(code)] = conn[offsets[:-1][sel][:, None] + np.arange(k[0])]
    return out


def runs(types: np.ndarray, offsets: np.ndarray) -> List[Tuple[int, int]]:
    """(start, end) of each run of cells of one type and one point count (meshio's blocks)."""
    key = types.astype(np.int64) << 32 | sizes(offsets)
    breaks = np.flatnonzero(key[1:] != key[:-1]) + 1
    edges = [0, *breaks.tolist(), len(types)]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def counts_text(counts: Mapping[str, int], n_cells: int, n_tets: Optional[int] = None) -> str:
    """"204300 cells (12600 hexahedron, 900 pyramid, ...), 318600 tets" for a repr."""
    kinds = ", ".join(f"{n} {name}" for name, n in counts.items())
    text = f"{n_cells} cells ({kinds})"
    return text if n_tets is None or n_tets == n_cells else f"{text}, {n_tets} tets"
