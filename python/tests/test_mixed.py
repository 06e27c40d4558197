"""Meshes of every cell type tetloc reads (tets, hexahedra, wedges, pyramids, their
higher-order kinds, and mixes) through every way in and out: ``tetloc.read``, pyvista,
meshio and the ``Mesh`` constructor. ``cells``/``celltypes``/``offsets`` are the input's
cells; ``tets`` the tets located in. The answers' oracle is geometry: the cells' corners'
convex hulls (scipy), and affine fields, which every cell type interpolates exactly."""

from __future__ import annotations

from typing import Any

import meshio
import numpy as np
import pytest
import pyvista as pv
import pyvista.examples.cells as example
from conftest import same_mesh

import tetloc

# pyvista's one-cell examples of every VTK volume type tetloc reads ...
READ = [
    "Tetrahedron", "Hexahedron", "Wedge", "Pyramid", "QuadraticTetrahedron", "QuadraticHexahedron",
    "QuadraticWedge", "QuadraticPyramid", "TriQuadraticHexahedron", "BiQuadraticQuadraticWedge",
    "LagrangeTetrahedron", "LagrangeHexahedron", "LagrangeWedge", "BezierTetrahedron",
]
# ... and of those it does not (with the name pyvista gives the type).
NOT_READ = {
    "BiQuadraticQuadraticHexahedron": "biquadratic_quadratic_hexahedron",
    "QuadraticLinearWedge": "quadratic_linear_wedge",
    "TriQuadraticPyramid": "triquadratic_pyramid",
    "BezierHexahedron": "bezier_hexahedron",
    "BezierWedge": "bezier_wedge",
    "Polyhedron": "polyhedron",
    "PentagonalPrism": "pentagonal_prism",
    "HexagonalPrism": "hexagonal_prism",
    "ConvexPointSet": "convex_point_set",
}


def with_fields(grid: pv.UnstructuredGrid) -> pv.UnstructuredGrid:
    """`grid` with an affine point field f (every cell type interpolates it exactly), a
    vector field v and a cell field c."""
    grid = grid.copy()
    p = np.asarray(grid.points, dtype=np.float64)
    grid.point_data["f"] = p @ [1.0, 2.0, 3.0] + 0.5
    grid.point_data["v"] = p
    grid.cell_data["c"] = np.arange(grid.n_cells, dtype=np.float64) + 0.25
    return grid


# Corners of each VTK type tetloc reads: the cell is their convex hull when its faces are planar.
CORNERS = {10: 4, 24: 4, 71: 4, 78: 4, 14: 5, 27: 5, 13: 6, 26: 6, 32: 6, 73: 6, 12: 8, 25: 8, 29: 8, 72: 8}


def hull_ids(mesh: tetloc.Mesh, pts: np.ndarray) -> np.ndarray:
    """The cell whose corners' convex hull holds each point (scipy), -1 in none."""
    from scipy.spatial import Delaunay

    out = np.full(len(pts), -1)
    p64, conn, offsets = mesh.points64, mesh.cell_connectivity, mesh.offsets
    for c, code in enumerate(mesh.celltypes):
        corners = p64[conn[offsets[c]:offsets[c] + CORNERS[int(code)]]]
        out[Delaunay(corners).find_simplex(pts) >= 0] = c
    return out


def agrees_with_geometry(mesh: tetloc.Mesh, n: int = 2000, seed: int = 0, grid: Any = None) -> None:
    """Random points around the mesh: each gets the cell that holds it (the oracle: the
    cells' corners' hulls: higher-order cells are located by their corners), and the affine f
    exactly (unless `grid`, the same cells in VTK, shows them curved)."""
    lo, hi = np.reshape(mesh.bounds, (3, 2)).T
    pts = np.random.default_rng(seed).uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), size=(n, 3))
    ids, f = tetloc.Locator(mesh, backend="cpu").locate_and_sample(pts, "f")
    want = hull_ids(mesh, pts)
    # Points within rounding of a shared face may go either way: a few, never many.
    assert (ids != want).sum() <= n // 500, f"{(ids != want).sum()} of {n} ids differ from the hulls'"
    assert (ids >= 0).sum() > n // 20
    inside = ids >= 0
    affine = pts[inside] @ [1.0, 2.0, 3.0] + 0.5
    if grid is not None:
        # A higher-order cell with nodes off their straight-sided places (pyvista's quadratic
        # pyramid) is curved: no cell type interpolates f exactly there, VTK neither.
        vtk_f = pv.PolyData(pts[inside]).sample(grid)["f"]
        if not np.allclose(vtk_f, affine, rtol=1e-6, atol=1e-6):
            return
    np.testing.assert_allclose(f[inside], affine, rtol=1e-4, atol=1e-4)
    assert np.isnan(f[~inside]).all()


@pytest.mark.parametrize("name", READ)
def test_every_cell_type_from_pyvista_and_back(name):
    grid = with_fields(getattr(example, name)())
    mesh = tetloc.Mesh.from_pyvista(grid)
    assert mesh.n_cells == 1 and mesh.celltypes.tolist() == grid.celltypes.tolist()
    assert mesh.offsets.tolist() == [0, grid.n_points]
    if grid.celltypes[0] not in (pv.CellType.TETRA, pv.CellType.QUADRATIC_TETRA, pv.CellType.LAGRANGE_TETRAHEDRON,
                                 pv.CellType.BEZIER_TETRAHEDRON):
        # Cells other than tets keep their nodes as given (tets: canonical corner order).
        np.testing.assert_array_equal(mesh.cell_connectivity, grid.cell_connectivity)
    np.testing.assert_array_equal(mesh.tet_cells, np.zeros(mesh.n_tets))
    agrees_with_geometry(mesh, grid=grid)
    back = mesh.to_pyvista()
    assert back.celltypes.tolist() == grid.celltypes.tolist()
    np.testing.assert_array_equal(back.cell_connectivity, mesh.cell_connectivity)
    np.testing.assert_array_equal(back.point_data["f"], grid.point_data["f"])
    np.testing.assert_array_equal(back.cell_data["c"], grid.cell_data["c"])
    same_mesh(tetloc.Mesh.from_pyvista(back), mesh)
    # The constructor takes pyvista's forms too: flat cells with celltypes, and blocks per type.
    point_data = {"f": grid.point_data["f"], "v": grid.point_data["v"]}
    cell_data = {"c": grid.cell_data["c"]}
    flat = tetloc.Mesh(grid.points, mesh.cells, point_data, cell_data, celltypes=mesh.celltypes)
    same_mesh(flat, mesh)
    same_mesh(tetloc.Mesh(grid.points, mesh.cells_dict, point_data, cell_data), mesh)


@pytest.mark.parametrize("name", READ)
def test_every_cell_type_through_meshio(name, tmp_path):
    grid = with_fields(getattr(example, name)())
    mesh = tetloc.Mesh.from_pyvista(grid)
    m = mesh.to_meshio()
    assert isinstance(m, meshio.Mesh) and len(m.cells) == 1
    same_mesh(tetloc.Mesh.from_meshio(m), mesh)
    # meshio's own reading of the grid's file (its node orders: its linear wedge is Gmsh's,
    # not VTK's) gives the same mesh.
    path = tmp_path / "cell.vtu"
    grid.save(path)
    try:
        read = meshio.read(path)
    except (KeyError, SystemExit):
        # This meshio names these types but cannot read them (no dimension listed for
        # wedge15, pyramid13 and Bezier tets; Lagrange hexahedra stop its VTU reader).
        assert name in ("QuadraticWedge", "QuadraticPyramid", "BezierTetrahedron", "LagrangeHexahedron")
        return
    same_mesh(tetloc.Mesh.from_meshio(read), mesh)


@pytest.mark.parametrize("name", sorted(NOT_READ))
def test_cell_types_tetloc_does_not_read_are_refused_by_name(name):
    grid = getattr(example, name)()
    with pytest.raises(ValueError, match=rf"pyvista grid: the mesh has cells that tetloc does not read \(1 {NOT_READ[name]}"):
        tetloc.Mesh.from_pyvista(grid)
    with pytest.raises(ValueError, match="tetloc does not read"):
        tetloc.Locator(grid)


def small_mixed_grid() -> pv.UnstructuredGrid:
    """A hexahedron, a pyramid on it, a wedge and a tet beside it, and a triangle (ignored)."""
    points = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1],  # hex
         [0.5, 0.5, 1.6],  # pyramid apex
         [2, 0, 0], [2, 1, 0], [2, 0, 1], [2, 1, 1],  # wedge: (1,0,0) (2,0,0) (1,1,0) / +z; and beyond
         [3, 0, 0]], dtype=np.float64)
    cells = {
        pv.CellType.HEXAHEDRON: np.array([[0, 1, 2, 3, 4, 5, 6, 7]]),
        pv.CellType.PYRAMID: np.array([[4, 5, 6, 7, 8]]),
        pv.CellType.WEDGE: np.array([[1, 9, 2, 5, 11, 6]]),
        pv.CellType.TETRA: np.array([[9, 13, 10, 11]]),
        pv.CellType.TRIANGLE: np.array([[0, 1, 2]]),
    }
    return with_fields(pv.UnstructuredGrid(cells, points))


def test_a_mixed_pyvista_grid_works_everywhere():
    grid = small_mixed_grid()
    volume = grid.celltypes != pv.CellType.TRIANGLE
    mesh = tetloc.Mesh.from_pyvista(grid)
    assert mesh.n_cells == 4 and mesh.n_tets > 4
    np.testing.assert_array_equal(mesh.celltypes, grid.celltypes[volume])
    np.testing.assert_array_equal(mesh.field("c"), grid.cell_data["c"][volume])  # the triangle's row dropped
    assert repr(mesh).startswith(f"tetloc.Mesh(4 cells (1 hexahedron, 1 pyramid, 1 tetra, 1 wedge), {mesh.n_tets} tets, ")
    assert sorted(mesh.info()["mesh"]["cell_types"].items()) == [("hexahedron", 1), ("pyramid", 1), ("tetra", 1), ("wedge", 1)]
    np.testing.assert_array_equal(np.unique(mesh.tet_cells), np.arange(4))
    agrees_with_geometry(mesh, n=4000)
    # Item 3: the filters and the Locator take it as pyvista input.
    ids = tetloc.Locator(grid, backend="cpu").locate(grid.cell_centers().points[volume])
    np.testing.assert_array_equal(ids, np.arange(4))
    img = tetloc.resample_to_image(grid, "f", dims=(9, 5, 5), backend="cpu")
    assert isinstance(img, pv.ImageData)
    inside = img.point_data["vtkValidPointMask"] == 1
    assert inside.sum() > 0
    np.testing.assert_allclose(img.point_data["f"][inside], img.points[inside] @ [1.0, 2.0, 3.0] + 0.5, rtol=1e-5)
    targets = pv.PolyData(np.vstack([grid.cell_centers().points[volume], [[5.0, 5.0, 5.0]]]))
    probed = tetloc.probe(grid, targets, "f", backend="cpu")
    np.testing.assert_array_equal(probed.point_data["vtkValidPointMask"], [1, 1, 1, 1, 0])
    # Round trips.
    same_mesh(tetloc.Mesh.from_pyvista(mesh.to_pyvista()), mesh)
    same_mesh(tetloc.Mesh.from_meshio(mesh.to_meshio()), mesh)
    assert [b.type for b in mesh.to_meshio().cells] == ["hexahedron", "pyramid", "wedge", "tetra"]


def test_images_are_hexahedra():
    """pyvista images cast to voxels: taken as the hexahedra they are."""
    img = pv.ImageData(dimensions=(3, 4, 2), spacing=(1.0, 0.5, 2.0))
    img.point_data["f"] = np.asarray(img.points) @ [1.0, 2.0, 3.0] + 0.5
    mesh = tetloc.Mesh.from_pyvista(img)
    assert mesh.n_cells == img.n_cells and (mesh.celltypes == pv.CellType.HEXAHEDRON).all()
    agrees_with_geometry(mesh)
    pts = np.asarray(img.cell_centers().points)
    np.testing.assert_array_equal(tetloc.Locator(img, backend="cpu").locate(pts), img.find_containing_cell(pts))


def test_constructor_refusals():
    points = np.eye(8, 3)
    with pytest.raises(ValueError, match=r"tetloc.Mesh\(points, cells\): the mesh has cells that tetloc does not read \(1 VTK type 42 "
                       r"with 4 points\); polyhedra \(VTK type 42\) handed over as cell arrays carry no faces: tetloc reads "
                       r"them from .vtu and .vtk files and OpenFOAM cases"):
        tetloc.Mesh(points, {42: [[0, 1, 2, 3]]})
    with pytest.raises(ValueError, match=r"\(1 VTK type 12 with 7 points\)"):
        tetloc.Mesh(points, {pv.CellType.HEXAHEDRON: [list(range(7))]})
    with pytest.raises(ValueError, match=r"cells: cell 1 \[0, 1, 2, 9\] names a vertex outside 0..7"):
        tetloc.Mesh(points, [8, *range(8), 4, 0, 1, 2, 9], celltypes=[12, 10])
    with pytest.raises(ValueError, match=r"cells: 2 celltypes but the array holds 2 more entries"):
        tetloc.Mesh(points, [4, 0, 1, 2, 3, 4, 0, 1, 2, 3, 7, 7], celltypes=[10, 10])
    with pytest.raises(ValueError, match=r"cell_data\['c'\]: shape \(3,\); expected \(2,\)"):
        tetloc.Mesh(points, {12: [list(range(8))], 10: [[0, 1, 2, 4]]}, cell_data={"c": [1, 2, 3]})


def test_mixed_files_round_trip(data_dir):
    """read -> to_pyvista -> from_pyvista, and through meshio, keeps the cells, points and
    fields, for mixed, higher-order and mixed higher-order files; the grid is VTK's reading."""
    for rel in ("mixed/hybrid.zlib.vtu", "real/notch_disp.vtu", "mixed/hexwarp.zlib.vtu"):
        path = data_dir / rel
        mesh = tetloc.read(path)
        grid = mesh.to_pyvista()
        vtk = pv.read(path)
        np.testing.assert_array_equal(grid.celltypes, vtk.celltypes, err_msg=rel)
        np.testing.assert_array_equal(grid.cell_connectivity, vtk.cell_connectivity, err_msg=rel)
        for name in mesh.point_data:
            np.testing.assert_array_equal(grid.point_data[name], np.asarray(vtk.point_data[name], grid.point_data[name].dtype))
        same_mesh(tetloc.Mesh.from_pyvista(grid), mesh)
        same_mesh(tetloc.Mesh.from_meshio(mesh.to_meshio()), mesh)
    # Higher-order tets (Gmsh tetra20): all their nodes, corners canonical.
    p3 = tetloc.read(data_dir / "real" / "P3.msh")
    assert set(p3.celltypes.tolist()) == {pv.CellType.LAGRANGE_TETRAHEDRON} and set(np.diff(p3.offsets)) == {20}
    same_mesh(tetloc.Mesh.from_pyvista(p3.to_pyvista()), p3)
    same_mesh(tetloc.Mesh.from_meshio(p3.to_meshio()), p3)
    # meshio's reading of the Gmsh file (tetra20 blocks in Gmsh's node order) is tetloc's.
    for rel in ("real/P3.msh", "real/ArmadilloP4.msh"):  # (meshio stops on mixed/hybrid.msh)
        ref = tetloc.read(data_dir / rel)
        got = tetloc.Mesh.from_meshio(meshio.read(data_dir / rel))
        np.testing.assert_array_equal(got.celltypes, ref.celltypes, err_msg=rel)
        np.testing.assert_array_equal(got.cell_connectivity, ref.cell_connectivity, err_msg=rel)
        np.testing.assert_array_equal(got.points64, ref.points64, err_msg=rel)


def test_generated_hybrid(cli, tmp_path):
    """The issue's mesh (`gen jets-hybrid`), smaller: read, repr, round trips, pyvista input."""
    import subprocess

    path = tmp_path / "hybrid.vtu"
    subprocess.run([cli, "gen", "jets-hybrid", "--cells", "20k", "-o", str(path)], check=True)
    mesh = tetloc.read(path)
    counts = mesh.info()["mesh"]["cell_types"]
    assert {"hexahedron", "pyramid", "wedge"} <= set(counts) and mesh.n_tets > mesh.n_cells
    assert f"{mesh.n_cells} cells (" in repr(mesh) and f"{mesh.n_tets} tets" in repr(mesh)
    assert mesh.cell_data == {name: (mesh.n_cells,) for name in mesh.cell_data}
    grid = mesh.to_pyvista()  # issue 30 item 4: cell data has one row per cell
    assert grid.n_cells == mesh.n_cells
    same_mesh(tetloc.Mesh.from_pyvista(grid), mesh)
    same_mesh(tetloc.Mesh.from_meshio(mesh.to_meshio()), mesh)
    same_mesh(tetloc.Mesh.from_pyvista(pv.read(path)), mesh)
    pts = np.asarray(grid.cell_centers().points)[::50]
    np.testing.assert_array_equal(tetloc.Locator(grid, backend="cpu").locate(pts), np.arange(0, mesh.n_cells, 50))
    img = tetloc.resample_to_image(grid, dims=(8, 8, 8), backend="cpu")
    assert img.point_data["vtkValidPointMask"].sum() > 0


def test_reading_hexahedra_costs_about_what_reading_their_tets_does(tmp_path):
    """Issue 30 item 7: a mesh of cells with planar quad faces (every face of a generated or
    structured mesh) took 30x longer to read than its tets: each face was proven planar by a
    heap-allocated exact sum. Now the exact orient3d decides it on the stack."""
    import time

    mesh = tetloc.Mesh.from_pyvista(pv.ImageData(dimensions=(31, 31, 31)))  # 27,000 hexahedra
    hexes, tets = tmp_path / "hexes.vtu", tmp_path / "tets.vtu"
    mesh.to_pyvista().save(hexes)
    pv.UnstructuredGrid({pv.CellType.TETRA: mesh.tets}, mesh.points).save(tets)  # their 162,000 tets

    def best(path) -> float:
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            tetloc.read(path)
            times.append(time.perf_counter() - t0)
        return min(times)

    t_hexes, t_tets = best(hexes), best(tets)
    assert t_hexes < 5 * t_tets + 0.1, f"27k hexahedra read in {t_hexes:.3f} s, their tets in {t_tets:.3f} s"
