"""Exodus II files written here with the ``netCDF4`` package in the layout SEACAS writes, in
both netCDF-4 (HDF5) and classic netCDF, read by tetloc and by VTK's ``vtkExodusIIReader``:
the same points, cells (types and node order), ids, steps and values. And the reader's errors
on bad files."""

from __future__ import annotations

import pathlib
from typing import Dict, List, Optional, Tuple

import numpy as np
import pytest
from conftest import missing

import tetloc

FORMATS = ["NETCDF4", "NETCDF3_64BIT_OFFSET"]
TIMES = [0.0, 0.25, 1.0]

# Each element type's nodes on its reference cell, in the Exodus II manual's order (edge
# nodes at the middle of the edge between the two 1-based corners named).
TET = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
HEX = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
WEDGE = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (0, 1, 1)]
PYRAMID = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 1)]
EDGES = {
    "TETRA10": (TET, [(1, 2), (2, 3), (3, 1), (1, 4), (2, 4), (3, 4)]),
    "HEX20": (HEX, [(1, 2), (2, 3), (3, 4), (4, 1), (1, 5), (2, 6), (3, 7), (4, 8), (5, 6), (6, 7), (7, 8), (8, 5)]),
    "WEDGE15": (WEDGE, [(1, 2), (2, 3), (3, 1), (1, 4), (2, 5), (3, 6), (4, 5), (5, 6), (6, 4)]),
    "PYRAMID13": (PYRAMID, [(1, 2), (2, 3), (3, 4), (4, 1), (1, 5), (2, 5), (3, 5), (4, 5)]),
}
CORNERS = {"TETRA4": TET, "HEX8": HEX, "WEDGE6": WEDGE, "PYRAMID5": PYRAMID, "QUAD4": HEX[:4]}


def reference_nodes(elem_type: str) -> np.ndarray:
    if elem_type in CORNERS:
        return np.array(CORNERS[elem_type], float)
    corners, edges = EDGES[elem_type]
    c = np.array(corners, float)
    return np.concatenate([c, [(c[a - 1] + c[b - 1]) / 2 for a, b in edges]])


class Block:
    """An element block: `n` elements of `elem_type`, each with nodes of its own, placed
    along x past the blocks before it (a small shear keeps the cells general)."""

    def __init__(self, elem_type: str, n: int) -> None:
        self.elem_type, self.n = elem_type, n


def build(blocks: List[Block]) -> Tuple[np.ndarray, List[np.ndarray]]:
    """The points and each block's connectivity (1-based, Exodus order)."""
    points: List[np.ndarray] = []
    conns = []
    rng = np.random.default_rng(7)
    shear = np.array([[1.0, 0.1, 0.05], [0.0, 1.0, 0.2], [0.0, 0.0, 0.9]])
    x = 0.0
    for b in blocks:
        ref = reference_nodes(b.elem_type)
        conn = []
        for _ in range(b.n):
            nodes = ref @ shear.T + [x, rng.uniform(-0.2, 0.2), 0.0]
            conn.append(np.arange(len(ref)) + sum(len(p) for p in points) + 1)
            points.append(nodes)
            x += 1.5
        conns.append(np.array(conn, np.int32))
    return np.concatenate(points), conns


def write_exodus(
    path: pathlib.Path,
    fmt: str,
    blocks: List[Block],
    node_vars: Optional[Dict[str, np.ndarray]] = None,
    elem_vars: Optional[Dict[str, List[Optional[np.ndarray]]]] = None,
    conns: Optional[List[np.ndarray]] = None,
    points: Optional[np.ndarray] = None,
) -> Tuple[np.ndarray, List[np.ndarray]]:
    """An Exodus II file as SEACAS lays it out: coordinates, element blocks, `time_whole`,
    nodal variables (steps, nodes), element variables per block (steps, elements; None where
    the truth table leaves the block out), node and element number maps. Returns the points
    and the connectivity written."""
    netCDF4 = need_netcdf4()
    if points is None or conns is None:
        points, conns = build(blocks)
    node_vars, elem_vars = node_vars or {}, elem_vars or {}
    with netCDF4.Dataset(str(path), "w", format=fmt) as nc:
        nc.title = "tetloc test_exodus"
        nc.api_version, nc.version, nc.floating_point_word_size = np.float32(8.0), np.float32(8.0), np.int32(8)
        nc.file_size, nc.maximum_name_length = np.int32(1), np.int32(32)
        for name, size in [("len_string", 33), ("len_name", 33), ("len_line", 81), ("four", 4), ("time_step", None),
                           ("num_dim", 3), ("num_nodes", len(points)), ("num_elem", sum(len(c) for c in conns)),
                           ("num_el_blk", len(blocks))]:
            nc.createDimension(name, size)

        def names(var: str, dim: str, values: List[str]) -> None:
            v = nc.createVariable(var, "S1", (dim, "len_name"))
            for i, s in enumerate(values):
                v[i, :] = netCDF4.stringtoarr(s, 33)

        names("coor_names", "num_dim", ["X", "Y", "Z"])
        for k, axis in enumerate("xyz"):
            nc.createVariable(f"coord{axis}", "f8", ("num_nodes",))[:] = points[:, k]
        nc.createVariable("eb_status", "i4", ("num_el_blk",))[:] = np.ones(len(blocks), np.int32)
        prop = nc.createVariable("eb_prop1", "i4", ("num_el_blk",))
        prop.setncattr("name", "ID")
        prop[:] = np.arange(len(blocks), dtype=np.int32) + 10
        names("eb_names", "num_el_blk", [f"block_{b.elem_type.lower()}" for b in blocks])
        for i, (b, conn) in enumerate(zip(blocks, conns), start=1):
            nc.createDimension(f"num_el_in_blk{i}", len(conn))
            nc.createDimension(f"num_nod_per_el{i}", conn.shape[1])
            c = nc.createVariable(f"connect{i}", "i4", (f"num_el_in_blk{i}", f"num_nod_per_el{i}"))
            c.elem_type = b.elem_type
            c[:] = conn
        nc.createVariable("node_num_map", "i4", ("num_nodes",))[:] = 1000 + 3 * np.arange(len(points), dtype=np.int32)
        n_elem = sum(len(c) for c in conns)
        nc.createVariable("elem_num_map", "i4", ("num_elem",))[:] = 500 + 7 * np.arange(n_elem, dtype=np.int32)
        time_whole = nc.createVariable("time_whole", "f8", ("time_step",))
        time_whole[:] = TIMES
        if node_vars:
            nc.createDimension("num_nod_var", len(node_vars))
            names("name_nod_var", "num_nod_var", list(node_vars))
            for i, values in enumerate(node_vars.values(), start=1):
                dim = "num_nodes" if values.shape[1] == len(points) else f"num_nodes_wrong{i}"
                if dim not in nc.dimensions:
                    nc.createDimension(dim, values.shape[1])
                nc.createVariable(f"vals_nod_var{i}", "f8", ("time_step", dim))[:] = values
        if elem_vars:
            nc.createDimension("num_elem_var", len(elem_vars))
            names("name_elem_var", "num_elem_var", list(elem_vars))
            table = np.array([[per_block[b] is not None for per_block in elem_vars.values()]
                              for b in range(len(blocks))], np.int32)
            nc.createVariable("elem_var_tab", "i4", ("num_el_blk", "num_elem_var"))[:] = table
            for i, per_block in enumerate(elem_vars.values(), start=1):
                for j, block_values in enumerate(per_block, start=1):
                    if block_values is not None:
                        v = nc.createVariable(f"vals_elem_var{i}eb{j}", "f8", ("time_step", f"num_el_in_blk{j}"))
                        v[:] = block_values
    return points, conns


def need_netcdf4():
    try:
        import netCDF4
    except ImportError:
        missing("netCDF4 is not installed")
    return netCDF4


def need_vtk():
    try:
        import vtk
        from vtk.util.numpy_support import vtk_to_numpy
    except ImportError:
        missing("vtk is not installed")
    return vtk, vtk_to_numpy


def vtk_blocks(path: pathlib.Path, step: int):
    """VTK's element blocks at `step`: for each, (cell types, each cell's node coordinates,
    point data, cell data), with the global ids."""
    vtk, to_numpy = need_vtk()
    r = vtk.vtkExodusIIReader()
    r.SetFileName(str(path))
    r.UpdateInformation()
    r.SetAllArrayStatus(vtk.vtkExodusIIReader.NODAL, 1)
    r.SetAllArrayStatus(vtk.vtkExodusIIReader.ELEM_BLOCK, 1)
    r.SetGenerateGlobalNodeIdArray(1)
    r.SetGenerateGlobalElementIdArray(1)
    r.SetTimeStep(step)
    r.Update()
    times = list(r.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS()) or [])
    out = r.GetOutput().GetBlock(0)  # the element blocks
    blocks = []
    for b in range(out.GetNumberOfBlocks()):
        g = out.GetBlock(b)
        pts = to_numpy(g.GetPoints().GetData()).astype(np.float64)
        types = np.array([g.GetCellType(c) for c in range(g.GetNumberOfCells())])
        cells = [pts[[g.GetCell(c).GetPointId(i) for i in range(g.GetCell(c).GetNumberOfPoints())]]
                 for c in range(g.GetNumberOfCells())]
        pd = {g.GetPointData().GetArrayName(i): to_numpy(g.GetPointData().GetArray(i))
              for i in range(g.GetPointData().GetNumberOfArrays())}
        cd = {g.GetCellData().GetArrayName(i): to_numpy(g.GetCellData().GetArray(i))
              for i in range(g.GetCellData().GetNumberOfArrays())}
        blocks.append((types, cells, pd, cd))
    return times, blocks


VOLUME_TYPES = ["TETRA4", "TETRA10", "HEX8", "HEX20", "WEDGE6", "WEDGE15", "PYRAMID5", "PYRAMID13"]


def variables(points: np.ndarray, conns: List[np.ndarray], skip_block: int):
    """A scalar `p` and a vector `vel` (as `vel_x/_y/_z`) on the nodes, and an element
    variable `rho` on every block but `skip_block`, each changing with the step."""
    t = np.array(TIMES)[:, None]
    x, y, z = points.T
    node = {"p": (x + 2 * y + 3 * z)[None, :] * (1 + t) + t,
            "vel_x": np.sin(y)[None, :] + t, "vel_y": np.cos(x)[None, :] * (1 + t), "vel_z": z[None, :] - t}
    start = np.cumsum([0] + [len(c) for c in conns])
    rho = [None if b == skip_block else (np.arange(start[b], start[b + 1])[None, :] * 0.5 + 10 * t)
           for b in range(len(conns))]
    return node, {"rho": rho}


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("blocks", ["all types", "tets only"])
def test_exodus_files_read_as_vtk_reads_them(tmp_path, fmt, blocks):
    """Every volume element type (quadratic ones with their Exodus node orders), a surface
    block that both skip, nodal and element variables over three steps, a truth table that
    leaves a block out, and the number maps: tetloc's mesh is VTK's, cell by cell, node by
    node, step by step. "tets only" takes the reader's path for meshes of linear tets."""
    kinds = VOLUME_TYPES + ["QUAD4"] if blocks == "all types" else ["TETRA4", "TETRA4"]
    bl = [Block(k, 2 + i % 2) for i, k in enumerate(kinds)]
    skip = 1
    points, conns = build(bl)
    node, elem = variables(points, conns, skip)
    path = tmp_path / ("mesh.e" if fmt == "NETCDF4" else "mesh.exo")
    write_exodus(path, fmt, bl, node_vars=node, elem_vars=elem, points=points, conns=conns)

    mesh = tetloc.read(path)
    assert mesh.times == TIMES
    np.testing.assert_array_equal(mesh.points64, points)
    grid = mesh.to_pyvista()
    volume = [b for b in range(len(bl)) if bl[b].elem_type != "QUAD4"]
    assert mesh.n_cells == sum(len(conns[b]) for b in volume)
    node_of_gid = {1000 + 3 * i: i for i in range(len(points))}
    for step in range(len(TIMES)):
        times, vblocks = vtk_blocks(path, step)
        np.testing.assert_allclose(times, TIMES)
        got_p, got_vel = mesh.field("p", step=step), mesh.field("vel", step=step)
        got_rho = mesh.field("rho", step=step)
        np.testing.assert_array_equal(got_p, node["p"][step])
        cell = 0
        assert len(vblocks) == len(bl)
        for b, (types, cells, pd, cd) in enumerate(vblocks):
            if b not in volume:
                continue
            for c in range(len(types)):
                assert grid.celltypes[cell] == types[c], f"block {b} cell {c}"
                # (VTK's reader keeps float32 points; tetloc the file's float64, checked below.)
                ours = grid.points[grid.get_cell(cell).point_ids].astype(np.float32)
                np.testing.assert_array_equal(ours, cells[c], err_msg=f"block {bl[b].elem_type} cell {c}")
                assert mesh.field("GlobalElementId")[cell] == cd["GlobalElementId"][c]
                if b == skip:
                    assert "rho" not in cd and np.isnan(got_rho[cell])
                else:
                    assert got_rho[cell] == cd["rho"][c]
                cell += 1
            nodes = np.array([node_of_gid[int(g)] for g in pd["GlobalNodeId"]])
            np.testing.assert_array_equal(mesh.field("GlobalNodeId")[nodes], pd["GlobalNodeId"])
            np.testing.assert_array_equal(got_p[nodes], pd["p"])
            # (VTK names the vector `vel_`, keeping the underscore; tetloc names it `vel`.)
            np.testing.assert_array_equal(got_vel[nodes], pd["vel_"])
        assert cell == mesh.n_cells


def test_a_tet_mesh_locates_the_same_from_both_encodings(tmp_path):
    """The two encodings of one tet mesh give the same mesh and the same located values."""
    bl = [Block("TETRA4", 3), Block("TETRA4", 2)]
    points, conns = build(bl)
    node, _ = variables(points, conns, -1)
    meshes = []
    for fmt in FORMATS:
        path = tmp_path / f"m_{fmt}.e"
        write_exodus(path, fmt, bl, node_vars={"p": node["p"]}, points=points, conns=conns)
        meshes.append(tetloc.read(path))
    a, b = meshes
    np.testing.assert_array_equal(a.points64, points)
    np.testing.assert_array_equal(a.points64, b.points64)
    np.testing.assert_array_equal(a.tets, np.concatenate(conns) - 1)
    np.testing.assert_array_equal(a.tets, b.tets)
    centres = np.array([points[c - 1].mean(axis=0) for c in np.concatenate(conns)], np.float32)
    for k in range(len(TIMES)):
        want = np.array([node["p"][k][c - 1].mean() for c in np.concatenate(conns)])
        for m in meshes:
            got = tetloc.Locator(m, backend="cpu").sample(centres, "p", step=k)
            np.testing.assert_allclose(got, want, rtol=1e-6)


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("kind", ["TETRA4", "HEX8"])
def test_a_node_id_out_of_range_names_the_element(tmp_path, fmt, kind):
    """A connectivity naming node 0 or a node past the last: the element, its block and the
    id, for the tets-only path and the general one."""
    bl = [Block(kind, 3)]
    points, conns = build(bl)
    for bad in (0, len(points) + 1):
        c = [conns[0].copy()]
        c[0][1, 2] = bad
        path = tmp_path / f"bad_{bad}.e"
        write_exodus(path, fmt, bl, points=points, conns=c)
        with pytest.raises(ValueError) as e:
            tetloc.read(path)
        msg = str(e.value)
        assert path.name in msg and f"element 2 of block 1 names node {bad}" in msg, msg
        assert f"the nodes are 1 to {len(points)}" in msg, msg


@pytest.mark.parametrize("fmt", FORMATS)
def test_bad_exodus_files_get_clear_errors(tmp_path, fmt):
    """An element type tetloc does not read, and a nodal variable whose length is not the
    node count: each an error naming the file and the problem."""
    bl = [Block("TETRA4", 2)]
    points, conns = build(bl)
    unknown = tmp_path / "unknown.e"
    write_exodus(unknown, fmt, [Block("HEX27", 1)], points=np.zeros((27, 3)),
                 conns=[np.arange(1, 28, dtype=np.int32)[None, :]])
    with pytest.raises(ValueError, match=r"unknown\.e.*HEX27.*27 nodes is not one tetloc reads"):
        tetloc.read(unknown)
    short = tmp_path / "short.e"
    p = np.zeros((len(TIMES), len(points) - 1))
    write_exodus(short, fmt, bl, node_vars={"p": p}, points=points, conns=conns)
    with pytest.raises(ValueError, match=rf"short\.e.*nodal variable 'p'.*has {len(points) - 1} values at step 0 "
                                         rf"but the mesh has {len(points)} nodes"):
        tetloc.read(short)
