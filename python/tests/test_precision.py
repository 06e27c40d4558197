"""float64 field values (issue 12.6): float64 points on a float64 field get float64 values,
interpolated in float64 (the CPU's, on every backend with ``precision="f64"``); float32
input keeps float32 values; a bad ``precision`` is a ValueError."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import exact_values, kuhn_grid

import tetloc


def near_zero_mesh() -> tetloc.Mesh:
    """A 4-cube Kuhn grid with a float64 field of values near zero that float32 cannot hold
    (``g``) and the same values rounded to float32 (``g32``)."""
    points, cells = kuhn_grid(4)
    points = points.astype(np.float64)
    g = 1e-9 + points[:, 0] * 1e-12 + 1e-3 * (points[:, 1] - (2.0 + 1e-7 / 3))
    return tetloc.Mesh(points, cells, point_data={"g": g, "g32": g.astype(np.float32)})


def query_points() -> np.ndarray:
    rng = np.random.default_rng(7)
    pts = rng.uniform(0.1, 3.9, (2000, 3))
    pts[:, 1] = 2.0 + rng.uniform(-1e-3, 1e-3, len(pts))  # where g is near zero
    return pts


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
def test_float64_points_on_a_float64_field_get_the_cpus_float64_values(backend, request):
    if backend != "cpu":
        request.getfixturevalue("vulkan")
    mesh, pts = near_zero_mesh(), query_points()
    cpu = tetloc.Locator(mesh, backend="cpu")
    ids, want = cpu.locate_and_sample(pts, "g")
    assert want.dtype == np.float64 and (ids >= 0).all()
    # f64 barycentrics on the f64 data: the values are the reference's, far beyond float32.
    g = 1e-9 + mesh.points64[:, 0] * 1e-12 + 1e-3 * (mesh.points64[:, 1] - (2.0 + 1e-7 / 3))
    ref = exact_values(mesh, ids, pts, g)
    assert np.abs(want - ref).max() <= 1e-9 * np.abs(ref).max()
    f32_path = cpu.sample(pts.astype(np.float32), "g")
    assert f32_path.dtype == np.float32, "float32 points keep float32 values"
    assert (np.abs(f32_path - ref) / np.abs(ref)).max() > 1e-5, "float32 cannot hold these values"
    # A float32 field gives float32 values, unless precision="f64".
    assert cpu.sample(pts, "g32").dtype == np.float32
    loc = tetloc.Locator(mesh, backend=backend, precision="f64")
    got_ids, got = loc.locate_and_sample(pts, "g")
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got_ids, ids)
    np.testing.assert_array_equal(got, want)  # bit for bit
    assert loc.sample(pts, "g32").dtype == np.float64
    np.testing.assert_array_equal(loc.sample(pts, "g32"), tetloc.Locator(mesh, backend="cpu", precision="f64").sample(pts, "g32"))


def test_a_bad_precision_is_a_value_error(grid_mesh):
    with pytest.raises(ValueError, match="precision 'bogus'"):
        tetloc.Locator(grid_mesh, backend="cpu", precision="bogus")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="precision"):
        tetloc.Locator(grid_mesh, backend="cpu", precision=64)  # type: ignore[arg-type]


def test_fields_come_back_as_the_file_holds_them(tmp_path):
    """A float64 field comes back float64, bit for bit (also through pyvista and a file), a
    float32 field float32."""
    mesh = near_zero_mesh()
    g = mesh.field("g")
    assert g.dtype == np.float64 and mesh.field("g32").dtype == np.float32
    want = 1e-9 + mesh.points64[:, 0] * 1e-12 + 1e-3 * (mesh.points64[:, 1] - (2.0 + 1e-7 / 3))
    np.testing.assert_array_equal(g, want)
    pv = pytest.importorskip("pyvista")
    grid = mesh.to_pyvista()
    assert isinstance(grid, pv.UnstructuredGrid) and grid.point_data["g"].dtype == np.float64
    path = tmp_path / "near_zero.vtu"
    grid.save(path)
    back = tetloc.read(path)
    np.testing.assert_array_equal(back.field("g"), g)
    assert back.field("g32").dtype == np.float32
    # Far from the origin the grid keeps the float64 coordinates.
    points, cells = kuhn_grid(2)
    far = tetloc.Mesh(points.astype(np.float64) + [512345.1, 4123456.3, 0.7], cells)
    np.testing.assert_array_equal(far.to_pyvista().points, far.points64)
