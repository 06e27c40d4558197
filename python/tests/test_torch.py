"""``tetloc.torch`` on CPU tensors: the numpy API's answers on the oracle sets and generated
meshes, autograd (gradcheck in float64 on tets and mixed cells), fill values, and clear errors
for bad tensors. The CUDA counterparts are scripts/h200/torch.sh (python/tests/cuda_torch.py)."""

from __future__ import annotations

import math
import subprocess
import sys
from typing import Optional

import numpy as np
import pytest
from conftest import REPO, in_ci, query_sets

import tetloc

try:
    import torch
except ImportError:
    if in_ci():
        raise
    pytest.skip("no torch (pip install torch)", allow_module_level=True)
import tetloc.torch as tt  # noqa: E402


def test_importing_tetloc_does_not_import_torch():
    code = "import sys, tetloc; assert 'torch' not in sys.modules, 'tetloc imported torch'"
    subprocess.run([sys.executable, "-c", code], check=True)


def compare_with_numpy(loc: tt.Locator, points: np.ndarray, name: Optional[str]) -> None:
    """ids identical to tetloc.Locator's, values of field `name` (if any) within rounding of
    its values (float32 ones where the numpy API answers float32), for float32 and float64
    points."""
    host = loc._host
    for dtype in (np.float32, np.float64):
        p = np.ascontiguousarray(points, dtype=dtype)
        ids = loc.locate(torch.from_numpy(p))
        assert ids.dtype == torch.int32 and ids.device.type == "cpu"
        np.testing.assert_array_equal(ids.numpy(), host.locate(p))
        if name is None:
            continue
        got = loc.sample(torch.from_numpy(p), name).numpy()
        want = host.sample(p, name)
        assert got.dtype == dtype and got.shape == want.shape
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        ok = ~np.isnan(want)
        scale = np.abs(want[ok]).max(initial=1.0)
        tol = 1e-5 if want.dtype == np.float32 else 1e-9
        np.testing.assert_allclose(got[ok], want[ok], rtol=0, atol=tol * scale)
        assert ok.sum() > 0


def test_oracle_sets_match_the_numpy_api(data_dir):
    sets = query_sets(data_dir) + query_sets(data_dir / "mixed")
    assert len(sets) >= 27, f"expected the oracle query sets of {data_dir} and mixed/"
    locators = {}
    for s in sets:
        if s.mesh_path not in locators:
            locators[s.mesh_path] = tt.Locator(tetloc.read(s.mesh_path), backend="cpu")
        loc = locators[s.mesh_path]
        compare_with_numpy(loc, s.points[:5000], "f" if "f" in loc.mesh.point_data else None)


def test_generated_meshes_match_the_numpy_api(grid_mesh):
    rng = np.random.default_rng(1)
    points = rng.uniform(-0.5, 6.5, size=(3000, 3))
    loc = tt.Locator(grid_mesh, backend="cpu")
    compare_with_numpy(loc, points, "f")
    compare_with_numpy(loc, points, "v")  # a vector field: (K, 3)
    compare_with_numpy(loc, points, "c")  # a cell field: constant per cell
    hexes = tt.Locator(hex_grid(4, jitter=0.2), backend="cpu")
    compare_with_numpy(hexes, rng.uniform(-0.1, 1.1, size=(3000, 3)), "f")


def hex_grid(n: int, jitter: float, seed: int = 3) -> tetloc.Mesh:
    """n^3 trilinear hexahedra on [0, 1]^3, interior vertices jittered by `jitter` x spacing,
    with f = sin(3x) + yz per point."""
    rng = np.random.default_rng(seed)
    ax = np.linspace(0.0, 1.0, n + 1)
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    inner = ((points > 0) & (points < 1)).all(axis=1)
    points[inner] += rng.uniform(-jitter, jitter, size=(inner.sum(), 3)) / n
    vid = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)  # noqa: E731
    k, j, i = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
    hexes = np.stack([vid(i, j, k), vid(i + 1, j, k), vid(i + 1, j + 1, k), vid(i, j + 1, k),
                      vid(i, j, k + 1), vid(i + 1, j, k + 1), vid(i + 1, j + 1, k + 1), vid(i, j + 1, k + 1)], axis=1)
    f = np.sin(3 * points[:, 0]) + points[:, 1] * points[:, 2]
    return tetloc.Mesh(points, {12: hexes}, point_data={"f": f})


def cell_points(mesh: tetloc.Mesh, n: int, seed: int = 0) -> np.ndarray:
    """`n` points well inside cells: each a random convex mix of a cell's corners, pulled to
    its centre (away from faces, where the interpolant's gradient jumps)."""
    rng = np.random.default_rng(seed)
    conn, offsets = mesh.cell_connectivity, mesh.offsets
    cells = rng.integers(0, mesh.n_cells, size=n)
    pts = mesh.points64
    out = np.empty((n, 3))
    for r, c in enumerate(cells):
        corners = pts[conn[offsets[c]:offsets[c + 1]]][: {8: 8, 6: 6, 5: 5}.get(offsets[c + 1] - offsets[c], 4)]
        mix = rng.dirichlet(np.ones(len(corners)))
        out[r] = 0.5 * corners.mean(axis=0) + 0.5 * mix @ corners
    return out


@pytest.mark.parametrize("kind", ["tets", "hexes", "hybrid"])
def test_gradcheck_float64(kind, grid_mesh, request):
    if kind == "tets":
        mesh = grid_mesh
    elif kind == "hexes":
        mesh = hex_grid(3, jitter=0.25)
    else:  # the oracle data's mixed mesh: hexahedra, pyramids, wedges and tets (a skip without it)
        mesh = tetloc.read(request.getfixturevalue("data_dir") / "mixed" / "hybrid.zlib.vtu")
    loc = tt.Locator(mesh, backend="cpu")
    points = torch.from_numpy(cell_points(mesh, 12)).requires_grad_(True)
    field = torch.randn(mesh.n_points, 2, dtype=torch.float64, requires_grad=True)
    # Every field entry is checked on the small meshes, random projections on the larger file.
    fast = mesh.n_points > 1000
    assert torch.autograd.gradcheck(lambda p, f: loc.sample(p, f), (points, field), eps=1e-6, atol=1e-6, fast_mode=fast)
    # The interpolant's gradient of a linear field in linear tets is the field's own.
    if kind == "tets":
        p = points.detach().clone().requires_grad_(True)
        loc.sample(p, "f").sum().backward()
        assert p.grad is not None
        np.testing.assert_allclose(p.grad.numpy(), np.tile([1.0, 2.0, 3.0], (len(p), 1)), atol=1e-9)


def test_the_gpu_tet_weights_are_the_cores(grid_mesh):
    """The barycentrics a GPU locator computes beside the points (in torch, for linear tets)
    against the core's (interpolation_weights), run here on the CPU."""
    loc = tt.Locator(grid_mesh, backend="cpu")
    rng = np.random.default_rng(4)
    points = torch.from_numpy(np.concatenate([cell_points(grid_mesh, 300), rng.uniform(-1, 7, size=(300, 3))]))
    field = torch.from_numpy(rng.normal(size=(grid_mesh.n_points, 2)))
    core = loc._weights(points, torch.float64, gradients=True)
    loc._tets, loc._vertices = torch.from_numpy(grid_mesh.tets), torch.from_numpy(grid_mesh.points64)
    gpu = loc._weights(points, torch.float64, gradients=True)
    np.testing.assert_array_equal(gpu.inside.numpy(), core.inside.numpy())
    np.testing.assert_array_equal(gpu.nodes.numpy()[core.inside], core.nodes.numpy()[core.inside])
    np.testing.assert_allclose(gpu.weights.numpy(), core.weights.numpy(), atol=1e-12)
    np.testing.assert_allclose(gpu.gradients.numpy(), core.gradients.numpy(), atol=1e-9)
    p = points.clone().requires_grad_(True)
    field = field.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda f: loc.sample(p, f, fill=0.0), (field,), fast_mode=True)
    loc.sample(p, field).sum().backward()
    assert p.grad is not None
    assert torch.isfinite(p.grad).all()


def test_a_nan_vertex_value_reaches_only_its_cells(data_dir):
    """Rows are padded to the widest cell (8 nodes of a hex) with weight 0: a NaN elsewhere
    must not leak into the padding of smaller cells."""
    mesh = tetloc.read(data_dir / "mixed" / "hybrid.zlib.vtu")
    loc = tt.Locator(mesh, backend="cpu")
    points = torch.from_numpy(cell_points(mesh, 2000, seed=2))
    cells = loc.locate(points).numpy()
    field = torch.ones(mesh.n_points, dtype=torch.float64)
    field[0] = math.nan
    values = loc.sample(points, field).numpy()
    conn, offsets = mesh.cell_connectivity, mesh.offsets
    holds_0 = np.array([0 in conn[offsets[c]:offsets[c + 1]] for c in cells])
    assert (~holds_0).sum() > 1000
    np.testing.assert_allclose(values[~holds_0], 1.0)
    # Outside points have zero gradients whatever the field holds.
    outside = torch.tensor([[1e3, 1e3, 1e3]], dtype=torch.float64, requires_grad=True)
    field.requires_grad_(True)
    loc.sample(outside, field, fill=0.0).sum().backward()
    assert outside.grad is not None and field.grad is not None
    assert outside.grad.eq(0).all() and field.grad.eq(0).all()


def test_field_gradient_is_the_transposed_interpolation(grid_mesh):
    loc = tt.Locator(grid_mesh, backend="cpu")
    points = torch.from_numpy(cell_points(grid_mesh, 200, seed=5))
    field = torch.zeros(grid_mesh.n_points, dtype=torch.float64, requires_grad=True)
    loc.sample(points, field).sum().backward()
    # Each point spreads weights summing to 1 over its cell's vertices.
    assert field.grad is not None
    assert abs(field.grad.sum().item() - 200) < 1e-9
    assert (field.grad >= 0).all()


def test_outside_points_get_the_fill_and_no_gradient(grid_mesh):
    loc = tt.Locator(grid_mesh, backend="cpu")
    points = torch.tensor([[1.2, 2.3, 3.4], [9.0, 9.0, 9.0]], dtype=torch.float64, requires_grad=True)
    field = torch.ones(grid_mesh.n_points, dtype=torch.float64, requires_grad=True)
    v = loc.sample(points, field)
    assert v[0].item() == pytest.approx(1.0) and torch.isnan(v[1])
    v = loc.sample(points, field, fill=-2.0)
    assert v[1].item() == -2.0
    (v * torch.tensor([1.0, 5.0], dtype=torch.float64)).sum().backward()
    assert points.grad is not None and field.grad is not None
    assert points.grad[1].abs().sum() == 0
    assert field.grad.sum().item() == pytest.approx(1.0)
    ids = loc.locate(points.detach())
    assert ids.tolist()[1] == -1


def test_bad_tensors_get_clear_errors(grid_mesh):
    loc = tt.Locator(grid_mesh, backend="cpu")
    good = torch.rand(10, 3) * 6
    with pytest.raises(TypeError, match="points: expected a torch.Tensor"):
        loc.locate(good.tolist())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="dtype torch.int64"):
        loc.locate(torch.ones(10, 3, dtype=torch.int64))
    with pytest.raises(ValueError, match=r"shape \(10, 4\)"):
        loc.locate(torch.rand(10, 4))
    with pytest.raises(ValueError, match="not contiguous"):
        loc.locate(torch.rand(3, 10).t())
    with pytest.raises(ValueError, match="on meta, but this Locator is on cpu"):
        loc.locate(torch.empty(10, 3, device="meta"))
    with pytest.raises(ValueError, match=f"field: shape \\(5,\\); expected vertex values \\({grid_mesh.n_points},\\)"):
        loc.sample(good, torch.ones(5))
    with pytest.raises(TypeError, match="field: dtype torch.int32"):
        loc.sample(good, torch.ones(grid_mesh.n_points, dtype=torch.int32))
    with pytest.raises(ValueError, match="field: on meta"):
        loc.sample(good, torch.empty(grid_mesh.n_points, device="meta"))
    with pytest.raises(ValueError, match="no field"):
        loc.sample(good, "nope")
    assert tt.host_copies() == 0


def test_dlpack_arrays_are_taken_without_a_copy(grid_mesh):
    """A DLPack array on the locator's device (numpy here; CuPy or JAX arrays on a GPU) is
    taken as a tensor that shares its memory: the answers are the tensor's, as points and as
    vertex values, and gradients reach a tensor built on the same memory."""
    loc = tt.Locator(grid_mesh, backend="cpu")
    p = np.random.default_rng(4).uniform(-0.5, 6.5, size=(2000, 3))
    for dtype in (np.float32, np.float64):
        pts = np.ascontiguousarray(p, dtype=dtype)
        t = torch.from_numpy(pts)
        assert torch.equal(loc.locate(pts), loc.locate(t))  # type: ignore[arg-type]
        got, want = loc.sample(pts, "f"), loc.sample(t, "f")  # type: ignore[arg-type]
        np.testing.assert_array_equal(got.numpy(), want.numpy())
    shared = tt._from_dlpack(pts, "points")
    assert isinstance(shared, torch.Tensor) and shared.data_ptr() == pts.ctypes.data, "not copied"
    values = np.ascontiguousarray(grid_mesh.field("f"), dtype=np.float64)
    got = loc.sample(pts, values)  # type: ignore[arg-type]
    np.testing.assert_array_equal(got.numpy(), loc.sample(t, torch.from_numpy(values)).numpy())
    assert tt.host_copies() == 0


def test_the_example_fits_a_field():
    example = REPO / "python" / "examples" / "torch_fit.py"
    args = ["--steps", "60", "--observations", "4000", "--cubes", "6", "--device", "cpu"]
    out = subprocess.run([sys.executable, str(example), *args], check=True, capture_output=True, text=True).stdout
    # It prints the misfit before and after: fitting must reduce it tenfold.
    first, last = (float(line.split()[-1]) for line in out.splitlines() if line.startswith("rms"))
    assert last < first / 10, out



def test_non_finite_points_go_far_outside_for_the_kernel():
    """The zero-copy path's guard: which points are finite, and the others moved far outside
    (the kernel gets those; their ids become -1 after it)."""
    from tetloc.torch import _finite_or_far

    p = torch.tensor([[0.5, 0.5, 0.5], [float("nan"), 0.0, 0.0], [0.0, float("inf"), 1.0], [1.0, 2.0, 3.0]])
    finite, safe = _finite_or_far(p)
    assert finite.tolist() == [True, False, False, True]
    assert torch.equal(safe[finite], p[finite]) and safe.is_contiguous()
    assert bool((safe[~finite] == 3.0e38).all())
