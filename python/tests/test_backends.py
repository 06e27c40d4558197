"""Every backend through the Python API on the machine's Vulkan device (lavapipe in CI):
the oracle sets of two meshes, the same answers as cpu, memory reports, device errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import query_sets
from test_oracle import check_set

import tetloc

GPU_BACKENDS = ["soft-bvh", "rt-bvh", "rt-rep-faces", "rt-shared-faces"]


@pytest.fixture(scope="module")
def torus(data_dir):
    return tetloc.read(data_dir / "torus_s.vtu")


@pytest.mark.parametrize("backend", GPU_BACKENDS)
def test_gpu_backend_matches_the_oracle(vulkan, oracle_sets, backend):
    """delaunay_s: slivers and inverted tets (the Rust tests run every set on every kernel)."""
    check_on_gpu(oracle_sets, backend)


@pytest.mark.parametrize("backend", GPU_BACKENDS)
def test_gpu_backend_matches_the_generated_oracle(vulkan, generated_data, backend):
    """The fresh-clone counterpart: a generated block, answers computed at test time."""
    check_on_gpu(query_sets(generated_data), backend)


def check_on_gpu(all_sets, backend: str) -> None:
    sets = [s for s in all_sets if s.label.startswith("delaunay_s.")]
    assert len(sets) == 3
    mesh = tetloc.read(sets[0].mesh_path)
    loc = tetloc.Locator(mesh, backend=backend)
    assert loc.backend == backend
    cpu = tetloc.Locator(mesh, backend="cpu")
    for s in sets:
        ids = check_set(loc, mesh, s)
        # Unambiguous points: the same tet as cpu.
        same = (ids == cpu.locate(s.points)) | s.ambiguous
        assert same.all(), f"{backend} {s.label}: ids differ from cpu at unambiguous points"


@pytest.mark.parametrize("backend", ["cpu", *GPU_BACKENDS])
def test_points_on_shared_vertices_and_edges_go_to_the_lowest_tet(vulkan, grid_mesh, backend):
    """The tie rule: a point held by several tets (a vertex, an edge's midpoint) goes to the
    lowest of their ids, on every backend. On this conforming grid the tets holding a vertex
    are those that have it, and those holding an edge's midpoint those that have the edge."""
    tets = grid_mesh.tets.astype(np.int64)
    ids = np.arange(len(tets))
    lowest = np.full(grid_mesh.n_points, len(tets))
    np.minimum.at(lowest, tets.ravel(), np.repeat(ids, 4))
    # Edges as (low, high) vertex pairs, each with its lowest tet.
    pairs = [(a, b) for a in range(4) for b in range(a + 1, 4)]
    ends = np.concatenate([np.sort(tets[:, [a, b]], axis=1) for a, b in pairs])
    owner = np.tile(ids, len(pairs))
    edges, inverse = np.unique(ends, axis=0, return_inverse=True)
    edge_lowest = np.full(len(edges), len(tets))
    np.minimum.at(edge_lowest, inverse.ravel(), owner)
    p = grid_mesh.points64
    points = np.concatenate([p, 0.5 * (p[edges[:, 0]] + p[edges[:, 1]])])
    got = tetloc.Locator(grid_mesh, backend=backend).locate(points)
    want = np.concatenate([lowest, edge_lowest])
    if backend in ("rt-rep-faces", "rt-shared-faces"):
        # These may lose points of the boundary surface (both rays leave the mesh at once:
        # crates/tetloc-vulkan/tests/cracks.rs); the points they find follow the rule.
        lost = got < 0
        assert np.isin(points[lost], [0.0, 6.0]).any(axis=1).all(), "a lost point is not on the boundary"
        got, want = got[~lost], want[~lost]
    np.testing.assert_array_equal(got, want)


def test_gpu_memory_report(vulkan, torus):
    loc = tetloc.Locator(torus, backend="soft-bvh")
    m = loc.memory()
    assert m["on"] == "device"
    assert 0 < m["final_bytes"] <= m["peak_bytes"]
    # The mesh itself is on the device: at least its vertices and tets.
    assert m["final_bytes"] >= torus.n_points * 12 + torus.n_cells * 16
    assert loc.build_seconds > 0


def test_vector_fields_and_shapes_on_the_gpu(vulkan, grid_mesh):
    rng = np.random.default_rng(3)
    pts = rng.uniform(-0.5, 6.5, size=(2, 50, 3))
    gpu = tetloc.Locator(grid_mesh, backend="soft-bvh")
    cpu = tetloc.Locator(grid_mesh, backend="cpu")
    assert gpu.locate(pts).shape == (2, 50)
    np.testing.assert_array_equal(gpu.locate(pts), cpu.locate(pts))
    # float64 points: on a float64 mesh the CPU interpolates with f64 barycentrics and the
    # GPU in f32 (this float32 mesh rounds them to float32 first).
    np.testing.assert_allclose(gpu.sample(pts, "v"), cpu.sample(pts, "v"), rtol=1e-6, atol=1e-5)
    np.testing.assert_array_equal(gpu.sample(pts, "w"), cpu.sample(pts, "w"))
    # float32 points: one definition, the same bits.
    p32 = pts.astype(np.float32)
    np.testing.assert_array_equal(gpu.sample(p32, "v"), cpu.sample(p32, "v"))
    assert gpu.locate(np.empty((0, 3), np.float32)).shape == (0,)


def test_auto_uses_cpu_on_a_cpu_vulkan_driver(vulkan, grid_mesh):
    # auto means what it means for the CLI: cpu on a CPU Vulkan driver, else the fastest
    # backend measured here (cached), which resolve() names without building.
    loc = tetloc.Locator(grid_mesh)
    assert loc.backend == tetloc._tetloc.resolve("auto")
    if vulkan["device_type"] == "cpu":
        assert loc.backend == "cpu"
    else:
        assert loc.backend in vulkan["backends"] + ["cpu"]


def test_a_device_that_does_not_exist_raises_device_error(vulkan, grid_mesh):
    bad = len(tetloc.devices()) + 5
    with pytest.raises(tetloc.DeviceError, match=f"index {bad} out of range"):
        tetloc.Locator(grid_mesh, backend="soft-bvh", device=bad)
    # auto with an explicit device that cannot be opened falls back to cpu, and says why.
    with pytest.warns(RuntimeWarning, match="auto"):
        assert tetloc.Locator(grid_mesh, device=bad).backend == "cpu"


def test_devices_lists_what_each_device_runs(vulkan):
    for d in tetloc.devices():
        assert {"index", "name", "driver", "device_type", "ray_tracing", "memory_bytes", "backends"} <= set(d)
        assert "soft-bvh" in d["backends"]
        assert ("rt-bvh" in d["backends"]) == d["ray_tracing"]


def test_rt_options(vulkan, torus, oracle_sets):
    s = next(s for s in oracle_sets if s.label == "torus_s.random")
    points, ambiguous = s.points[:5000], s.ambiguous[:5000]
    want = tetloc.Locator(torus, backend="cpu").locate(points)
    for opts in ({"split": None}, {"split": 10_000, "compact": False}):
        got = tetloc.Locator(torus, backend="rt-bvh", **opts).locate(points)
        assert ((got == want) | ambiguous).all(), opts
