"""What the API takes and what it refuses: points in every accepted layout (and no copy
where none is needed), bad shapes, dtypes, NaN, empty and non-contiguous arrays, unknown
fields, backends and options, bad files. Every refusal is a Python exception that names
the argument or file."""

from __future__ import annotations

import os
import subprocess
import sys
from typing import Any, List

import numpy as np
import pytest

import tetloc
from tetloc._points import as_points


@pytest.fixture(scope="module")
def loc(grid_mesh):
    return tetloc.Locator(grid_mesh, backend="cpu")


@pytest.fixture(scope="module")
def pts():
    return np.random.default_rng(1).uniform(-1, 7, size=(1000, 3))


def test_a_c_contiguous_float32_array_is_used_without_a_copy(pts):
    a = pts.astype(np.float32)
    flat, lead = as_points(a)
    assert flat is a and lead == (1000,)
    view, _ = as_points(a[10:20])  # a contiguous slice is still not copied
    assert np.shares_memory(view, a)


def test_every_layout_gives_the_same_answers(loc, pts):
    want = loc.locate(pts.astype(np.float32))
    f32 = pts.astype(np.float32)
    layouts = {
        "float64": pts,
        "fortran f32": np.asfortranarray(f32),
        "fortran f64": np.asfortranarray(pts),
        "big-endian": f32.astype(">f4"),
        "strided": np.repeat(f32, 2, axis=0)[::2],
        "transposed view": np.ascontiguousarray(f32.T).T,
        "list": f32.tolist(),
        "read-only": np.frombuffer(f32.tobytes(), np.float32).reshape(-1, 3),
    }
    for name, p in layouts.items():
        np.testing.assert_array_equal(loc.locate(p), want, err_msg=name)
    assert loc.locate([[1, 1, 1]]).shape == (1,)  # a list of ints is numbers too
    grid = f32.reshape(10, 100, 3)
    np.testing.assert_array_equal(loc.locate(grid), want.reshape(10, 100))
    assert loc.locate(f32[0]).shape == () and loc.locate(f32[0]) == want[0]
    assert loc.sample(grid, "v").shape == (10, 100, 3)


class DLPackOnly:
    """A tensor that offers only DLPack (as array-API libraries do)."""

    def __init__(self, a: np.ndarray):
        self._a = a

    def __dlpack__(self, **kwargs):
        return self._a.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self._a.__dlpack_device__()


class ArrayOnly:
    def __init__(self, a: np.ndarray):
        self._a = a

    def __array__(self, dtype=None, copy=None):
        return self._a if dtype is None else self._a.astype(dtype)


def test_tensors_through_dlpack_or_array(loc, pts):
    f32 = pts.astype(np.float32)
    want = loc.locate(f32)
    np.testing.assert_array_equal(loc.locate(DLPackOnly(f32)), want)
    np.testing.assert_array_equal(loc.locate(ArrayOnly(f32)), want)
    flat, _ = as_points(DLPackOnly(f32))
    assert np.shares_memory(flat, f32)


def test_torch_cpu_tensors(loc, pts):
    torch = pytest.importorskip("torch")  # not a test dependency: runs where torch is installed
    t = torch.from_numpy(pts.astype(np.float32))
    np.testing.assert_array_equal(loc.locate(t), loc.locate(pts))
    np.testing.assert_array_equal(loc.locate(t.double().T.contiguous().T), loc.locate(pts))


def test_empty_points(loc):
    empties: List[Any] = [np.empty((0, 3), np.float32), np.empty((0, 3)), []]
    for empty in empties:
        if isinstance(empty, list):
            with pytest.raises(ValueError, match="shape"):
                loc.locate(empty)
            continue
        assert loc.locate(empty).shape == (0,) and loc.locate(empty).dtype == np.int32
        assert loc.sample(empty, "f").shape == (0,)
        assert loc.sample(empty, "v").shape == (0, 3)
        ids, vals = loc.locate_and_sample(empty, "w")
        assert ids.shape == (0,) and vals.shape == (0, 2)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((5, 2)), r"points: shape \(5, 2\); expected \(K, 3\)"),
        (np.zeros((3, 5)), r"points: shape \(3, 5\)"),
        (np.zeros(()), r"points: shape \(\)"),
        (np.zeros((5, 3), np.float16), "points: dtype float16"),
        (np.zeros((5, 3), np.complex64), "points: dtype complex64"),
        (np.array([["a", "b", "c"]]), "points: dtype <U1"),
        ([[0, 0], [1, 1, 1]], "points: not an array of numbers"),
    ],
)
def test_bad_points_raise_value_error(loc, bad, match):
    with pytest.raises(ValueError, match=match):
        loc.locate(bad)
    with pytest.raises(ValueError, match=match):
        loc.sample(bad, "f")


def test_integer_points_are_numbers(loc, pts):
    """As numpy takes them: integer arrays answer as the same float64 points (lists of ints too)."""
    ints = np.round(pts).astype(np.int64)
    want_ids, want_f = loc.locate(ints.astype(np.float64)), loc.sample(ints.astype(np.float64), "f")
    for dt in (np.int8, np.int32, np.int64, np.uint16, np.uint64, bool):
        p = np.clip(ints, 0, None).astype(dt) if dt in (np.uint16, np.uint64, bool) else ints.astype(dt)
        np.testing.assert_array_equal(loc.locate(p), loc.locate(p.astype(np.float64)), err_msg=str(dt))
    np.testing.assert_array_equal(loc.locate(ints.astype(np.int32)), want_ids)
    np.testing.assert_array_equal(loc.sample(ints.astype(np.int32), "f"), want_f)
    np.testing.assert_array_equal(loc.locate(ints.tolist()), want_ids)


@pytest.mark.parametrize("bad", [None, 3, 2.5, "points", {"x": 1}])
def test_points_of_the_wrong_kind_raise_type_error(loc, bad):
    match = rf"points: expected an array-like of points of shape \(K, 3\) .*, got {type(bad).__name__}"
    with pytest.raises(TypeError, match=match):
        loc.locate(bad)
    with pytest.raises(TypeError, match=match):
        loc.sample(bad, "f")


@pytest.mark.parametrize("bad", [None, 0, 1.5, b"f", ["f"]])
def test_field_names_of_the_wrong_kind_raise_type_error(loc, pts, bad):
    match = rf"field name: expected a str, got {type(bad).__name__}"
    with pytest.raises(TypeError, match=match):
        loc.sample(pts, bad)
    with pytest.raises(TypeError, match=match):
        loc.locate_and_sample(pts, bad)


@pytest.mark.parametrize(
    "coords", [[0.5, np.nan, 0.5], [0.5, 0.5, np.inf], [0.5, 0.5, 1e300]], ids=["nan", "inf", "beyond-float32"]
)
def test_non_finite_points_are_outside_with_a_warning(loc, pts, coords):
    # As pyvista and the CLI: that point is -1 / NaN, the others are answered as without it.
    batch = np.vstack([pts[:3], [coords], pts[3:6]]).astype(np.float64)
    with pytest.warns(RuntimeWarning, match=r"1 of 7 points have a NaN or infinite coordinate"):
        ids = loc.locate(batch)
    with pytest.warns(RuntimeWarning):
        vals = loc.sample(batch, "f")
    good = np.delete(batch, 3, axis=0)
    np.testing.assert_array_equal(np.delete(ids, 3), loc.locate(good))
    np.testing.assert_array_equal(np.delete(vals, 3), loc.sample(good, "f"))
    assert ids[3] == -1 and np.isnan(vals[3])


def test_unknown_field(loc, pts):
    with pytest.raises(ValueError, match=r"no field named 'nope' \(the mesh has: 'f' \(point\), 'v' \(point, 3 comp"):
        loc.sample(pts, "nope")
    with pytest.raises(ValueError, match="no field named 'v\\[0\\]'"):  # components are not fields
        loc.locate_and_sample(pts, "v[0]")


def test_unknown_backend_device_and_options(grid_mesh):
    with pytest.raises(ValueError, match=r"unknown backend 'gpu' \(known: cpu, soft-bvh"):
        tetloc.Locator(grid_mesh, backend="gpu")
    # Every keyword is listed, the named ones too.
    every = "backend, device, progress, tolerance, split, compact, precision, deferred"
    # The typed options (tetloc.LocatorOptions) are the ones the extension knows.
    assert every == ", ".join(["backend", "device", *tetloc.LocatorOptions.__annotations__])
    with pytest.raises(TypeError, match=rf"Locator\(\) got an unexpected option 'leaf' \(known: {every}\)"):
        tetloc.Locator(grid_mesh, backend="cpu", leaf=4)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match=rf"unexpected option 'devise' \(known: {every}\)"):
        tetloc.Locator(grid_mesh, devise=0)  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="precision 'bogus'"):
        tetloc.Locator(grid_mesh, precision="bogus")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="split: expected a positive number"):
        tetloc.Locator(grid_mesh, split=0)
    with pytest.raises(TypeError, match="deferred: expected True or False"):
        tetloc.Locator(grid_mesh, backend="cpu", deferred="later")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="mesh: expected a tetloc.Mesh or a pyvista dataset, got str"):
        tetloc.Locator("mesh.vtu")


def test_a_gpu_backend_without_vulkan_raises_device_error():
    """Without a Vulkan driver (none listed for the loader, in a fresh interpreter), GPU
    backends raise DeviceError, auto falls back to cpu and devices() is empty."""

    code = (
        "import numpy as np, tetloc\n"
        "from conftest import kuhn_grid\n"
        "m = tetloc.Mesh(*kuhn_grid(2))\n"
        "assert tetloc.devices() == []\n"
        "assert tetloc.Locator(m).backend == 'cpu'\n"
        "try:\n"
        "    tetloc.Locator(m, backend='soft-bvh')\n"
        "except tetloc.DeviceError as e:\n"
        "    print('DeviceError:', e)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "VK_ICD_FILENAMES"}
    env["VK_DRIVER_FILES"] = "/nonexistent/none.json"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         cwd=os.path.dirname(__file__))
    assert out.returncode == 0, out.stderr
    assert "DeviceError: soft-bvh: no Vulkan device" in out.stdout


def test_bad_meshes(data_dir, tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        tetloc.read(tmp_path / "missing.vtu")
    assert e.value.filename == str(tmp_path / "missing.vtu")
    # Mixed meshes read (issue 13); cells tetloc does not read are refused, counted by type.
    assert tetloc.read(data_dir / "real" / "can.vtu").info()["mesh"]["cell_types"] == {"hexahedron": 4800}
    with pytest.raises(ValueError, match=r"penta_hexa.vtk: the mesh has volume cells that tetloc does not read \(60 pentagonal prism"):
        tetloc.read(data_dir / "real" / "penta_hexa.vtk")
    truncated = tmp_path / "truncated.vtu"
    truncated.write_bytes((data_dir / "torus_s.vtu").read_bytes()[:50_000])
    with pytest.raises(ValueError, match="truncated.vtu"):
        tetloc.read(truncated)
    for name in ("dir.vtu", "dir"):  # a directory is named as one, whatever its name
        (tmp_path / name).mkdir()
        with pytest.raises(IsADirectoryError, match=r"is a directory and not an OpenFOAM case; tetloc.read takes a mesh file") as isdir:
            tetloc.read(tmp_path / name)
        assert isdir.value.filename == str(tmp_path / name)


def test_bad_mesh_arrays():
    points = np.eye(4, 3)
    cells = np.array([[0, 1, 2, 3]])
    with pytest.raises(ValueError, match=r"points: shape \(4, 2\)"):
        tetloc.Mesh(points[:, :2], cells)
    with pytest.raises(ValueError, match=r"cells: shape \(1, 3\), dtype int64; expected \(M, 4\) integer vertex ids of tets"):
        tetloc.Mesh(points, cells[:, :3])
    with pytest.raises(ValueError, match="cells: .* dtype float64"):
        tetloc.Mesh(points, cells.astype(float))
    with pytest.raises(ValueError, match=r"cells: row 0 \[0, 1, 2, 4\] names a vertex outside 0..3"):
        tetloc.Mesh(points, [[0, 1, 2, 4]])
    with pytest.raises(ValueError, match="cells: row 0 .* outside"):
        tetloc.Mesh(points, [[0, 1, 2, -1]])
    with pytest.raises(ValueError, match="vertex 1 has a non-finite coordinate"):
        tetloc.Mesh(np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0], [0, 0, 1]]), cells)
    with pytest.raises(ValueError, match="the mesh has no tetrahedra"):
        tetloc.Mesh(points, np.empty((0, 4), int))
    with pytest.raises(ValueError, match=r"the mesh has no tetrahedra"):
        tetloc.Mesh(points, {10: np.empty((0, 4), int)})
    with pytest.raises(ValueError, match=r"point_data\['f'\]: shape \(3,\); expected \(4,\) or \(4, k\)"):
        tetloc.Mesh(points, cells, point_data={"f": [1, 2, 3]})
    with pytest.raises(ValueError, match=r"cell_data\['c'\]: dtype <U1"):
        tetloc.Mesh(points, cells, cell_data={"c": ["a"]})
    with pytest.raises(ValueError, match=r"given twice: \['v\[0\]'\]"):
        tetloc.Mesh(points, cells, point_data={"v": np.eye(4, 2), "v[0]": np.ones(4)})
    # Any integer dtype for cells; non-contiguous inputs are fine.
    for dt in (np.int8, np.uint16, np.int64, np.uint64):
        assert tetloc.Mesh(points, cells.astype(dt)).n_cells == 1
    assert tetloc.Mesh(np.asfortranarray(points), np.asfortranarray(cells)).n_cells == 1


def test_tolerance_answers_points_just_outside(grid_mesh):
    # The grid spans [0, 6]^3 and f = x + 2y + 3z. A point 0.01 outside the face x = 6 is
    # outside exactly; within a tolerance of 0.05 (or 5% of the mean edge, about 0.06) it gets
    # a tet on that face and f at the closest boundary point (6, 2.5, 3.5).
    p = np.array([[6.01, 2.5, 3.5], [3.0, 3.0, 3.0], [7.0, 3.0, 3.0]])
    exact = tetloc.Locator(grid_mesh, backend="cpu")
    assert exact.locate(p)[0] == -1
    for tolerance in (0.05, "5%"):
        loc = tetloc.Locator(grid_mesh, backend="cpu", tolerance=tolerance)
        ids, vals = loc.locate_and_sample(p, "f")
        assert ids[0] >= 0 and vals[0] == pytest.approx(6 + 2 * 2.5 + 3 * 3.5, rel=1e-6)
        assert ids[1] == exact.locate(p)[1]  # inside: unchanged
        assert ids[2] == -1  # farther than the tolerance
    for bad, err in [(-1.0, ValueError), ("x%", ValueError), ([1], TypeError)]:
        with pytest.raises(err, match="tolerance"):
            tetloc.Locator(grid_mesh, backend="cpu", tolerance=bad)  # type: ignore[arg-type]


def test_locator_takes_a_pyvista_dataset(grid_mesh, pts):
    pv = pytest.importorskip("pyvista")
    grid = grid_mesh.to_pyvista()
    loc = tetloc.Locator(grid, backend="cpu")
    assert isinstance(loc.mesh, tetloc.Mesh) and loc.mesh.n_cells == grid.n_cells
    np.testing.assert_array_equal(loc.locate(pts), tetloc.Locator(grid_mesh, backend="cpu").locate(pts))
    # VTK's answers too, but for a point on a face shared by two cells (either is right).
    assert (loc.locate(pts) != np.asarray(grid.find_containing_cell(pts))).sum() <= 2
    assert isinstance(grid, pv.DataSet)


def test_trace_warns_about_seeds_outside(grid_mesh):
    seeds = np.array([[1.0, 1.2, 1.3], [9.0, 9.0, 9.0], [2.0, 2.5, 3.1], [-1.0, 0.5, 0.5], [20.0, 0.0, 0.0]])
    with pytest.warns(RuntimeWarning, match=r"trace: 3 of 5 lines have no step inside the mesh"):
        out = tetloc.trace(grid_mesh, "v", seeds, max_steps=5, backend="cpu")
    assert len(out["offsets"]) - 1 == 2 and out["SeedIds"].tolist() == [0, 2]
    with pytest.warns(RuntimeWarning, match=r"trace: 6 of 10 lines"):
        tetloc.trace(grid_mesh, "v", seeds, max_steps=5, direction="both", backend="cpu")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # seeds all inside: no warning
        tetloc.trace(grid_mesh, "v", seeds[[0, 2]], max_steps=5, backend="cpu")


def test_pieces_outside_the_listing_are_refused_unless_allowed(cli, tmp_path):
    """Issue 29 item 20, as the CLI's `--allow-outside-pieces`: a .pvtu naming pieces outside
    its folder tree (here `../m/...`) is refused by default, naming the listing and the keyword
    that allows it; ``allow_outside_pieces=True`` reads it."""
    mesh, pvtu = tmp_path / "m.vtu", tmp_path / "m.pvtu"
    subprocess.run([cli, "gen", "jets", "--cells", "3000", "-q", "-o", str(mesh)], check=True)
    subprocess.run([cli, "partition", str(mesh), "--parts", "2", "-q", "-o", str(pvtu)], check=True)
    (tmp_path / "sub").mkdir()
    listing = tmp_path / "sub" / "up.pvtu"
    listing.write_text(pvtu.read_text().replace('Source="m/', 'Source="../m/'))
    with pytest.raises(ValueError, match=r"up\.pvtu.*outside the listing's folder.*allow_outside_pieces=True"):
        tetloc.read(listing)
    whole = tetloc.read(mesh)
    pieces = tetloc.read(listing, allow_outside_pieces=True)
    assert pieces.n_cells == whole.n_cells
    # The listing inside its folder reads without the keyword.
    assert tetloc.read(pvtu).n_cells == whole.n_cells
