"""The Mesh and Locator API on a mesh with known answers: properties, scalar and vector
fields on points and cells, memory reports, progress output, docstrings."""

from __future__ import annotations

import io

import numpy as np
import pytest
from conftest import exact_values, kuhn_grid

import tetloc
from tetloc._progress import ProgressBar


def test_mesh_properties(grid_mesh):
    assert (grid_mesh.n_points, grid_mesh.n_cells) == (7**3, 6 * 6**3)
    assert grid_mesh.bounds == (0.0, 6.0, 0.0, 6.0, 0.0, 6.0)
    assert grid_mesh.point_data == {"f": (343,), "v": (343, 3)}
    assert grid_mesh.cell_data == {"c": (1296,), "w": (1296, 2)}
    assert grid_mesh.points.dtype == np.float32 and grid_mesh.points.shape == (343, 3)
    # Cells as pyvista has them; for a mesh of tets, `tets` are the cells.
    assert grid_mesh.n_tets == 1296 and grid_mesh.tets.dtype == np.int64 and grid_mesh.tets.shape == (1296, 4)
    assert (grid_mesh.celltypes == 10).all() and grid_mesh.celltypes.shape == (1296,)
    np.testing.assert_array_equal(grid_mesh.offsets, 4 * np.arange(1297))
    np.testing.assert_array_equal(grid_mesh.cell_connectivity, grid_mesh.tets.ravel())
    np.testing.assert_array_equal(grid_mesh.cells.reshape(-1, 5), np.insert(grid_mesh.tets, 0, 4, axis=1))
    np.testing.assert_array_equal(grid_mesh.cells_dict[10], grid_mesh.tets)
    np.testing.assert_array_equal(grid_mesh.tet_cells, np.arange(1296))
    np.testing.assert_array_equal(grid_mesh.field("v"), grid_mesh.points)
    assert "1296 cells (1296 tetra), 343 points" in repr(grid_mesh) and "v[3]" in repr(grid_mesh)


def test_info_reports_the_mesh(grid_mesh):
    info = grid_mesh.info()
    assert info["mesh"]["n_tets"] == 1296 and info["mesh"]["n_points"] == 343
    assert info["mesh"]["n_reoriented"] > 0  # half the Kuhn tets are inverted as given
    assert info["mesh"]["total_volume"] == pytest.approx(216.0)
    assert info["faces"]["n_boundary"] == 6 * 6 * 6 * 2
    words = [{k: f[k] for k in ("name", "location", "min", "max")} for f in info["fields"]]
    assert {"name": "v[2]", "location": "vertex", "min": 0.0, "max": 6.0} in words  # the CLI's words


def test_locate_and_sample_known_answers(grid_mesh):
    rng = np.random.default_rng(2)
    pts = rng.uniform(-1, 7, size=(20_000, 3))
    loc = tetloc.Locator(grid_mesh, backend="cpu")
    ids = loc.locate(pts)
    p32 = pts.astype(np.float32)
    outside = (p32 < 0).any(axis=1) | (p32 > 6).any(axis=1)
    np.testing.assert_array_equal(ids < 0, outside)
    f = loc.sample(pts, "f")
    np.testing.assert_allclose(f[~outside], (p32.astype(np.float64) @ [1, 2, 3])[~outside], rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(f, exact_values(grid_mesh, ids, p32, grid_mesh.field("f")), rtol=1e-5, atol=1e-5)
    assert np.isnan(f[outside]).all()
    v = loc.sample(pts, "v")
    assert v.shape == (20_000, 3) and v.dtype == np.float32
    np.testing.assert_allclose(v[~outside], p32[~outside], atol=1e-5)
    c = loc.sample(pts, "c")
    np.testing.assert_array_equal(c[~outside], ids[~outside].astype(np.float32))
    ids2, w = loc.locate_and_sample(pts, "w")
    np.testing.assert_array_equal(ids2, ids)
    np.testing.assert_array_equal(w[~outside], np.stack([ids, -ids], axis=1)[~outside].astype(np.float32))
    assert np.isnan(w[outside]).all()


def test_tets_in_the_given_order_whatever_their_orientation():
    points, cells = kuhn_grid(2)
    flipped = cells[:, [1, 0, 2, 3]]  # every tet inverted: reoriented, same ids
    a = tetloc.Locator(tetloc.Mesh(points, cells), backend="cpu")
    b = tetloc.Locator(tetloc.Mesh(points, flipped), backend="cpu")
    pts = np.random.default_rng(4).uniform(0, 2, (5000, 3))
    np.testing.assert_array_equal(a.locate(pts), b.locate(pts))


def test_cpu_memory_report(grid_mesh):
    loc = tetloc.Locator(grid_mesh, backend="cpu")
    m = loc.memory()
    assert m["on"] == "host" and loc.backend == "cpu"
    assert m["items"]["mesh tets"] == 16 * grid_mesh.n_cells
    assert m["items"]["tet neighbours"] == 16 * grid_mesh.n_cells
    assert m["final_bytes"] == sum(m["items"].values()) <= m["peak_bytes"]


def test_progress_bar_on_a_build():
    out = io.StringIO()
    bar = ProgressBar("tetloc cpu", stream=out, after_seconds=0)
    mesh = tetloc.Mesh(*kuhn_grid(20))
    loc = tetloc.Locator(mesh, backend="cpu", progress=bar)
    text = out.getvalue()
    assert "tetloc cpu: BVH" in text and text.endswith("\n"), text
    out.truncate(0)
    loc.locate(np.random.default_rng(0).uniform(0, 20, (3 << 20, 3)))  # 3 chunks
    assert "locating on cpu [" in out.getvalue() and "done" in out.getvalue()
    # progress=True draws on stderr, only after half a second.
    assert tetloc.Locator(mesh, backend="cpu", progress=True).backend == "cpu"


def test_every_public_name_has_a_docstring():
    for name in tetloc.__all__:
        obj = getattr(tetloc, name)
        if callable(obj):
            assert obj.__doc__, name
    for cls in (tetloc.Mesh, tetloc.Locator):
        for attr, member in vars(cls).items():
            if not attr.startswith("_"):
                assert (getattr(member, "__doc__", None) or getattr(member, "fget", None).__doc__), f"{cls}.{attr}"
    assert set(tetloc.BACKENDS) == {"cpu", "soft-bvh", "rt-bvh", "rt-rep-faces", "rt-shared-faces"}


def test_docstrings_describe_every_cell_type_and_format():
    """Issue 30 item 6: no stale "tetrahedral only" text; the formats read are listed."""
    doc = tetloc.read.__doc__ or ""
    assert "non-tet" not in doc and "not tetrahedra" not in doc
    for fmt in (".vtu", ".pvtu", ".vtm", ".vtk", ".msh", ".node"):
        assert fmt in doc, fmt
    for text in (tetloc.Mesh.__doc__, tetloc.read.__doc__, tetloc.Mesh.from_pyvista.__doc__, tetloc.Mesh.from_meshio.__doc__):
        assert text is not None
        assert "hexahedra" in text or "hexahedron" in text
    assert "tetrahedral mesh" not in (tetloc.Mesh.__doc__ or "")
    locate_doc = tetloc.Locator.locate.__doc__ or ""
    assert "cells" in locate_doc and "tets containing" not in locate_doc


def test_the_package_is_typed():
    """Issue 28: type checkers see the package's types: ``py.typed`` and the extension's stub
    ship with it, and the Locator's keyword options are a TypedDict."""
    import pathlib

    here = pathlib.Path(tetloc.__file__).parent
    assert (here / "py.typed").is_file() and (here / "_tetloc.pyi").is_file()
    opts: tetloc.LocatorOptions = {"tolerance": "1%", "precision": "f64", "deferred": True}
    assert set(opts) <= set(tetloc.LocatorOptions.__annotations__)
