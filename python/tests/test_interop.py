"""pyvista and meshio in and out: round trips keep points, tets, fields and answers."""

from __future__ import annotations

import subprocess
import sys

import meshio
import numpy as np
import pytest
import pyvista as pv
from conftest import same_mesh

import tetloc


def test_pyvista_round_trip(grid_mesh):
    grid = grid_mesh.to_pyvista()
    assert isinstance(grid, pv.UnstructuredGrid)
    assert (grid.n_points, grid.n_cells) == (grid_mesh.n_points, grid_mesh.n_cells)
    assert (grid.celltypes == pv.CellType.TETRA).all()
    np.testing.assert_array_equal(grid.point_data["v"], grid_mesh.field("v"))
    np.testing.assert_array_equal(grid.cell_data["w"], grid_mesh.field("w"))
    np.testing.assert_allclose(grid.bounds, grid_mesh.bounds)
    # Canonical tets are right-handed, as VTK wants them: no negative volumes.
    assert (grid.compute_cell_sizes(length=False, area=False)["Volume"] > 0).all()
    same_mesh(tetloc.Mesh.from_pyvista(grid), grid_mesh)


def test_from_pyvista_answers_like_vtk(data_dir):
    """A file read by pyvista (VTK) gives the mesh tetloc reads, and ids VTK agrees with."""
    grid = pv.read(data_dir / "torus_s.vtu")
    mesh = tetloc.Mesh.from_pyvista(grid)
    ref = tetloc.read(data_dir / "torus_s.vtu")
    same_mesh(mesh, ref)
    pts = np.asarray(grid.cell_centers().points[::7])
    ids = tetloc.Locator(mesh, backend="cpu").locate(pts)
    np.testing.assert_array_equal(ids, np.arange(0, grid.n_cells, 7))
    vtk_ids = grid.find_containing_cell(pts)
    np.testing.assert_array_equal(ids, vtk_ids)


def test_from_pyvista_keeps_volumes_ignores_surfaces_refuses_other_cells():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    grid = pv.UnstructuredGrid(
        {pv.CellType.TRIANGLE: np.array([[0, 1, 2]]), pv.CellType.TETRA: np.array([[0, 1, 2, 3], [1, 2, 3, 4]])}, points
    )
    grid.cell_data["id"] = np.arange(3)
    mesh = tetloc.Mesh.from_pyvista(grid)
    assert mesh.n_cells == 2
    # VTK orders cells by the dict's type order; the triangle's row is dropped from the data.
    kept = np.asarray(grid.celltypes) == pv.CellType.TETRA
    np.testing.assert_array_equal(mesh.field("id"), np.arange(3)[kept])
    prisms = pv.UnstructuredGrid({pv.CellType.PENTAGONAL_PRISM: np.arange(10)[None]}, np.random.rand(10, 3))
    with pytest.raises(ValueError, match=r"pyvista grid: the mesh has cells that tetloc does not read \(1 pentagonal_prism\)"):
        tetloc.Mesh.from_pyvista(prisms)
    with pytest.raises(ValueError, match="pyvista grid: the mesh has no volume cells"):
        tetloc.Mesh.from_pyvista(pv.Sphere())
    with pytest.raises(TypeError, match="grid: expected a pyvista dataset, got ndarray"):
        tetloc.Mesh.from_pyvista(np.zeros(3))


def test_from_pyvista_higher_order_tets_keep_their_nodes():
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    mids = [(corners[a] + corners[b]) / 2 for a, b in ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))]
    grid = pv.UnstructuredGrid({pv.CellType.QUADRATIC_TETRA: np.arange(10)[None]}, np.vstack([corners, mids]))
    mesh = tetloc.Mesh.from_pyvista(grid)
    assert mesh.n_cells == 1 and mesh.n_tets == 1 and sorted(mesh.tets[0]) == [0, 1, 2, 3]
    assert mesh.celltypes.tolist() == [pv.CellType.QUADRATIC_TETRA] and mesh.cells[0] == 10
    assert sorted(mesh.cell_connectivity) == list(range(10))
    assert tetloc.Locator(mesh, backend="cpu").locate([[0.1, 0.1, 0.1]])[0] == 0


def test_meshio_round_trip(grid_mesh, tmp_path, data_dir):
    m = meshio.Mesh(
        grid_mesh.points,
        [("tetra", grid_mesh.tets)],
        point_data={"f": grid_mesh.field("f"), "v": grid_mesh.field("v")},
        cell_data={"c": [grid_mesh.field("c")], "w": [grid_mesh.field("w")]},
    )
    same_mesh(tetloc.Mesh.from_meshio(m), grid_mesh)
    # A file through meshio and through tetloc's own reader.
    path = tmp_path / "grid.vtu"
    meshio.write(path, m)
    same_mesh(tetloc.Mesh.from_meshio(meshio.read(path)), tetloc.read(path))
    # A Gmsh file with surface blocks beside the tets (the cell data of those is dropped).
    gm = meshio.read(data_dir / "part_s.meshio.msh")
    mesh = tetloc.Mesh.from_meshio(gm)
    ref = tetloc.read(data_dir / "part_s.meshio.msh")
    assert mesh.n_cells == ref.n_cells
    np.testing.assert_array_equal(np.sort(mesh.tets, axis=1), np.sort(ref.tets, axis=1))
    same_mesh(tetloc.Mesh.from_meshio(grid_mesh.to_meshio()), grid_mesh)


def test_from_meshio_refuses_cells_tetloc_does_not_read():
    # VTK has no Lagrange pyramid node order, so tetloc reads none (nor the files' readers).
    m = meshio.Mesh(np.eye(14, 3), [("VTK_LAGRANGE_PYRAMID", [list(range(14))]), ("tetra", [[0, 1, 2, 3]])])
    with pytest.raises(ValueError, match=r"meshio mesh: the mesh has cells that tetloc does not read \(1 VTK_LAGRANGE_PYRAMID\)"):
        tetloc.Mesh.from_meshio(m)
    with pytest.raises(ValueError, match="meshio mesh: the mesh has no volume cells"):
        tetloc.Mesh.from_meshio(meshio.Mesh(np.eye(3, 3), [("triangle", [[0, 1, 2]])]))


def test_pyvista_and_meshio_are_imported_only_when_used():
    code = "import sys, tetloc; print('pyvista' in sys.modules, 'meshio' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
