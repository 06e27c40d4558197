"""Time series (Exodus II, .pvd), steps through Mesh.field/Locator.sample, and the weights
of "locate once, interpolate many" (Locator.weights)."""

from __future__ import annotations

import json
import pathlib
import warnings
from typing import Any, Dict

import numpy as np
import pytest

import tetloc
from conftest import kuhn_grid

SERIES = ["part_s.e", "part_s.classic.exo", "part_s.pvd"]


@pytest.fixture(scope="module")
def time_dir(data_dir) -> pathlib.Path:
    return data_dir / "time"


@pytest.fixture(scope="module")
def oracle(data_dir, time_dir):
    points = np.fromfile(data_dir / "part_s.random.points.bin", dtype=np.float32).reshape(-1, 3)
    readme = json.loads((time_dir / "README.json").read_text())
    return points, np.load(time_dir / "part_s.random.values_by_step.npy"), readme["times"]


@pytest.mark.parametrize("name", SERIES)
def test_every_step_matches_the_oracle(time_dir, oracle, name):
    points, want, times = oracle
    mesh = tetloc.read(time_dir / name)
    assert mesh.times == times
    loc = tetloc.Locator(mesh, backend="cpu")
    W = loc.weights(points)
    assert W.shape == (len(points), mesh.n_points)
    for k in range(len(times)):
        got = loc.sample(points, "f", step=k)
        np.testing.assert_allclose(got, want[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(W @ mesh.field("f", step=k), want[k], rtol=1e-12, atol=1e-12)
        # The mesh at that step, for the operations that take a mesh.
        at = mesh.at_step(k)
        np.testing.assert_allclose(tetloc.probe(at, points, backend="cpu")["f"], want[k], rtol=1e-12, atol=1e-12)
    # Step 0 is what the mesh holds.
    np.testing.assert_array_equal(mesh.field("f", step=0), mesh.field("f"))
    with pytest.raises(ValueError, match="out of range"):
        mesh.field("f", step=len(times))
    with pytest.raises(ValueError, match="out of range"):
        loc.sample(points, "f", step=99)
    with pytest.raises(TypeError):
        mesh.field("f", step=1.0)  # type: ignore[arg-type]


def test_the_three_encodings_hold_the_same_steps(time_dir):
    meshes = [tetloc.read(time_dir / n) for n in SERIES]
    for m in meshes[1:]:
        np.testing.assert_array_equal(m.points64, meshes[0].points64)
        for k in range(len(m.times)):
            np.testing.assert_array_equal(m.field("f", step=k), meshes[0].field("f", step=k))


def test_a_snapshot_has_no_steps(grid_mesh, data_dir):
    mesh = tetloc.read(data_dir / "part_s.vtu")
    assert mesh.times == []
    with pytest.raises(ValueError, match="no time steps"):
        mesh.field("f", step=0)


def test_weights_equal_sample_on_every_mixed_cell_type(data_dir):
    for name in ["hexwarp", "hybrid", "prisms"]:
        mesh = tetloc.read(data_dir / "mixed" / f"{name}.zlib.vtu")
        points = np.fromfile(data_dir / "mixed" / f"{name}.random.points.bin", dtype=np.float32).reshape(-1, 3)
        loc = tetloc.Locator(mesh, backend="cpu")
        W = loc.weights(points)
        ids, f = loc.locate_and_sample(points, "f")
        inside = ids >= 0
        assert inside.sum() > len(points) // 2
        np.testing.assert_array_equal(W.getnnz(axis=1) > 0, inside)
        np.testing.assert_allclose((W @ mesh.field("f"))[inside], f[inside], rtol=1e-6, atol=1e-6)
        # Cell fields need only the ids.
        np.testing.assert_array_equal(mesh.field("g")[ids[inside]].astype(np.float32), loc.sample(points, "g")[inside])


def test_step_weights_sample_every_step_on_cpu_and_gpu(time_dir, oracle, vulkan, no_validation_errors):
    """Locate once, interpolate many: every step of the series at once, on the host and on the
    GPU (the weights on the device, a batch of steps a dispatch), as the oracle; the two agree
    bit for bit on a device with float64 (both sum in float64, round to float32)."""
    points, want, times = oracle
    mesh = tetloc.read(time_dir / "part_s.e")
    got = {}
    for backend in ["cpu", "soft-bvh"]:
        sw = tetloc.Locator(mesh, backend=backend).step_weights(points)
        assert (sw.device == "cpu") == (backend == "cpu"), sw.device
        assert sw.n_points == len(points) and "StepWeights" in repr(sw)
        got[backend] = sw.sample("f")
        assert got[backend].shape == (len(times), len(points)) and got[backend].dtype == np.float32
        np.testing.assert_allclose(got[backend], want, rtol=1e-6, atol=1e-6)
        # Some steps, in any order; and steps held in memory.
        np.testing.assert_array_equal(sw.sample("f", steps=[4, 1]), got[backend][[4, 1]])
        steps = np.stack([mesh.field("f", step=k) for k in range(len(times))])
        np.testing.assert_array_equal(sw.apply(steps), got[backend])
        with pytest.raises(ValueError, match="out of range"):
            sw.sample("f", steps=[len(times)])
        with pytest.raises(ValueError, match="expected \\(steps, "):
            sw.apply(np.zeros((2, mesh.n_points + 1), np.float32))
    if vulkan["float64"]:
        np.testing.assert_array_equal(got["soft-bvh"], got["cpu"])
    else:
        np.testing.assert_allclose(got["soft-bvh"], got["cpu"], rtol=1e-5, atol=1e-6)


def test_step_weights_apply_is_the_matrix(data_dir, vulkan, no_validation_errors):
    """On mixed and quadratic cells: ``apply`` of steps of k components equals ``W @ values``,
    points outside NaN; cell fields by each point's cell."""
    meshes = [tetloc.read(data_dir / "mixed" / "hybrid.zlib.vtu"), quadratic_tets()]
    rng = np.random.default_rng(5)
    for mesh in meshes:
        lo, hi = np.min(mesh.points64, 0), np.max(mesh.points64, 0)
        pts = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), size=(2000, 3))
        for backend in ["cpu", "soft-bvh"]:
            loc = tetloc.Locator(mesh, backend=backend)
            sw = loc.step_weights(pts)
            W = sw.matrix
            assert (W != loc.weights(pts)).nnz == 0
            inside = sw.cells >= 0
            assert 0 < inside.sum() < len(pts)
            values = rng.normal(size=(3, mesh.n_points, 2)).astype(np.float32)
            got = sw.apply(values)
            assert got.shape == (3, len(pts), 2)
            for s in range(3):
                np.testing.assert_allclose(got[s][inside], (W @ values[s].astype(np.float64))[inside], rtol=1e-5, atol=1e-6)
            assert np.isnan(got[:, ~inside]).all()
            # A scalar field: (S, K).
            assert sw.apply(values[:, :, 0]).shape == (3, len(pts))
            np.testing.assert_allclose(sw.sample("f")[0][inside], loc.sample(pts, "f")[inside], rtol=1e-5, atol=1e-6)
            if "g" in mesh.cell_data:
                g = sw.sample("g")[0]
                np.testing.assert_array_equal(g[inside], mesh.field("g")[sw.cells[inside]].astype(np.float32))
                assert np.isnan(g[~inside]).all()
            # No step: no value (not a reshape error); values that are not real numbers are
            # refused (complex ones lost their imaginary parts).
            assert sw.apply(values[:0]).shape == (0, len(pts), 2)
            assert sw.apply(values[:0, :, 0]).shape == (0, len(pts))
            for bad in (values.astype(np.complex64), values.astype(object)):
                with pytest.raises(TypeError, match="real numbers"):
                    sw.apply(bad)


def quadratic_tets(n: int = 3):
    """Kuhn tets with their 6 edge nodes (VTK's order), moved off the edges (curved), and a
    field that is not linear."""
    points, tets = kuhn_grid(n, spacing=1.0 / n)
    edges = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    mids = {}
    conn = []
    pts = [tuple(p) for p in points]
    for t in tets:
        row = list(t)
        for a, b in edges:
            key = (min(t[a], t[b]), max(t[a], t[b]))
            if key not in mids:
                m = (points[t[a]] + points[t[b]]) / 2
                mids[key] = len(pts)
                pts.append(tuple(m + 0.02 * np.sin(7 * m)))
            row.append(mids[key])
        conn.append(row)
    xyz = np.array(pts)
    f = np.sin(3 * xyz[:, 0]) + xyz[:, 1] * xyz[:, 2]
    padded = np.hstack([np.full((len(conn), 1), 10), np.array(conn)]).ravel()  # pyvista's [n, ids...]
    return tetloc.Mesh(xyz, padded, celltypes=np.full(len(conn), 24), point_data={"f": f})


def test_weights_equal_sample_on_quadratic_tets():
    mesh = quadratic_tets()
    pts = np.random.default_rng(3).uniform(-0.1, 1.1, size=(3000, 3))
    loc = tetloc.Locator(mesh, backend="cpu")
    W = loc.weights(pts)
    ids, f = loc.locate_and_sample(pts, "f")
    inside = ids >= 0
    assert W.getnnz(axis=1)[inside].tolist() == [10] * inside.sum()
    np.testing.assert_allclose((W @ mesh.field("f"))[inside], f[inside], rtol=1e-6, atol=1e-6)
    assert (W.getnnz(axis=1)[~inside] == 0).all()


def test_cli_time_steps(cli, time_dir, oracle, tmp_path):
    import subprocess

    points, want, times = oracle
    pts = tmp_path / "p.npy"
    np.save(pts, points.astype(np.float64))
    run = lambda *a: subprocess.run([cli, *map(str, a)], capture_output=True, text=True)  # noqa: E731
    info = run("info", time_dir / "part_s.e", "--json")
    assert info.returncode == 0, info.stderr
    assert json.loads(info.stdout)["times"] == times
    r = run("locate", time_dir / "part_s.e", "--points", pts, "--field", "f", "--out", tmp_path / "o.csv",
            "--backend", "cpu", "--time-step", "3")
    assert r.returncode == 0, r.stderr
    got = np.genfromtxt(tmp_path / "o.csv", delimiter=",", names=True)["f"]
    np.testing.assert_allclose(got, want[3], rtol=1e-12, atol=1e-12)
    r = run("probe", time_dir / "part_s.pvd", pts, "-o", tmp_path / "probe.vtp", "--backend", "cpu", "--time-step", "all")
    assert r.returncode == 0, r.stderr
    index = (tmp_path / "probe.pvd").read_text()
    assert all((tmp_path / f"probe_{k}.vtp").exists() and f"probe_{k}.vtp" in index for k in range(len(times)))
    r = run("locate", time_dir / "part_s.e", "--points", pts, "--out", tmp_path / "x.npy", "--time-step", "6")
    assert r.returncode != 0 and "out of range" in r.stderr, r.stderr
    r = run("locate", time_dir.parent / "part_s.vtu", "--points", pts, "--out", tmp_path / "x.npy", "--time-step", "0")
    assert r.returncode != 0 and "no time steps" in r.stderr, r.stderr


def spin_series(tmp_path: pathlib.Path, times, hexes: bool = False) -> pathlib.Path:
    """A .pvd over a unit cube of tets (or of hexahedra) whose `v` rotates about x = y = 0.5 at
    the angular speed w(t) = 1 + t: linear in space and time, so interpolation is exact and a
    particle turns by (t - t0) + (t^2 - t0^2) / 2."""
    import pyvista as pv

    if hexes:
        n = 6
        ijk = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)[:, ::-1]
        points = ijk.astype(np.float64) / n
        at = lambda i, j, k: (k * (n + 1) + j) * (n + 1) + i  # noqa: E731
        cells = np.array([[at(i, j, k), at(i + 1, j, k), at(i + 1, j + 1, k), at(i, j + 1, k),
                           at(i, j, k + 1), at(i + 1, j, k + 1), at(i + 1, j + 1, k + 1), at(i, j + 1, k + 1)]
                          for k in range(n) for j in range(n) for i in range(n)])
        grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, points)
    else:
        points, cells = kuhn_grid(6, 1.0 / 6)
        grid = pv.UnstructuredGrid({pv.CellType.TETRA: cells}, points)
    entries = []
    for k, t in enumerate(times):
        w = 1.0 + t
        grid.point_data["v"] = np.stack([-w * (points[:, 1] - 0.5), w * (points[:, 0] - 0.5), 0 * points[:, 0]], 1)
        grid.save(tmp_path / f"s_{k}.vtu")
        entries.append(f'<DataSet timestep="{t!r}" part="0" file="s_{k}.vtu"/>')
    pvd = tmp_path / "spin.pvd"
    pvd.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n'
                   + "\n".join(entries) + "\n</Collection>\n</VTKFile>\n")
    return pvd


def test_a_mesh_at_a_step(tmp_path):
    """Mesh.at_step(k): the same mesh with step k's fields (its steps kept), so streamlines,
    probes and locators run on that step: the same as on step k's file read alone. Only step
    k's file is read: the geometry is the mesh's own (step 0's file may be gone)."""
    mesh = tetloc.read(spin_series(tmp_path, [0.0, 0.5, 1.0, 1.5]))
    (tmp_path / "s_0.vtu").rename(tmp_path / "moved.vtu")
    at = mesh.at_step(3)
    assert at.times == mesh.times and at.n_tets == mesh.n_tets
    np.testing.assert_array_equal(at.field("v"), mesh.field("v", step=3))
    np.testing.assert_array_equal(at.field("v", step=1), mesh.field("v", step=1))
    alone = tetloc.read(tmp_path / "s_3.vtu")
    seeds = np.array([[0.8, 0.5, 0.3], [0.5, 0.2, 0.7]], np.float32)
    lines, want = (tetloc.trace(m, "v", seeds, backend="cpu", max_steps=50) for m in (at, alone))
    for name in want:
        np.testing.assert_array_equal(lines[name], want[name], err_msg=name)
    assert not np.array_equal(lines["v"], tetloc.trace(mesh, "v", seeds, backend="cpu", max_steps=50)["v"])
    pts = np.random.default_rng(1).uniform(0.1, 0.9, (100, 3)).astype(np.float32)
    np.testing.assert_array_equal(tetloc.probe(at, pts, backend="cpu")["v"], tetloc.probe(alone, pts, backend="cpu")["v"])
    with pytest.raises(ValueError, match="out of range"):
        mesh.at_step(4)
    with pytest.raises(ValueError, match="no time steps"):
        alone.at_step(0)
    with pytest.raises(TypeError):
        mesh.at_step(1.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
@pytest.mark.parametrize("hexes", [False, True])
def test_pathlines_follow_the_closed_form(tmp_path, backend, hexes):
    """RK4 in time with step h: one step's phase error is r (w h)^5 / 120 for a rotation; 20
    steps of h = 0.1 with w <= 3 and r <= 0.3 stay below 20 * 0.3 * 0.3^5 / 120 = 1.2e-4, and
    a factor 10 covers the terms from w' (and float32 lookups). On tets, and on hexahedra
    (refused before: their cells' interpolation against VTK's is the CLI's test
    pathlines_through_hexahedra_match_vtk_particle_paths)."""
    pvd = spin_series(tmp_path, [0.0, 0.5, 1.0, 1.5, 2.0], hexes)
    mesh = tetloc.read(pvd)
    assert mesh.times == [0.0, 0.5, 1.0, 1.5, 2.0]
    seeds = np.array([[0.8, 0.5, 0.3], [0.5, 0.2, 0.7]], np.float32)
    out = tetloc.trace(mesh, "v", seeds, unsteady=True, step=0.1, backend=backend)
    assert list(out["offsets"]) == [0, 5, 10]
    assert list(out["ReasonForTermination"]) == [7, 7]
    assert list(out["SeedIds"]) == [0, 1]
    t = out["IntegrationTime"]
    np.testing.assert_allclose(t[:5], [0.0, 0.5, 1.0, 1.5, 2.0])
    theta = t + 0.5 * t * t
    s = np.repeat(seeds.astype(np.float64), 5, axis=0) - [0.5, 0.5, 0.0]
    want = np.stack([0.5 + np.cos(theta) * s[:, 0] - np.sin(theta) * s[:, 1],
                     0.5 + np.sin(theta) * s[:, 0] + np.cos(theta) * s[:, 1], s[:, 2]], 1)
    assert np.abs(out["points"] - want).max() < 1.2e-3
    # The vector is recorded at the points, interpolated in time: w(t) r at radius r.
    speed = np.linalg.norm(out["v"], axis=1)
    np.testing.assert_allclose(speed, (1 + t) * np.linalg.norm(s[:, :2], axis=1), rtol=1e-3)
    # Between steps: injected at 0.25, stopped at 1.75.
    part = tetloc.trace(mesh, "v", seeds, unsteady=True, start_time=0.25, end_time=1.75, backend=backend)
    np.testing.assert_allclose(part["IntegrationTime"][:5], [0.25, 0.5, 1.0, 1.5, 1.75])


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
def test_pathline_vorticity(tmp_path, backend):
    """vorticity=True with unsteady=True: the spin's curl (0, 0, 2 w(t)) at every point, the
    injection between two steps included (the curl interpolated in time); it is across the
    flow, so no angular velocity and no rotation; no Normals (vtkParticlePathFilter writes
    none); the same arrays on the PolyData."""
    mesh = tetloc.read(spin_series(tmp_path, [0.0, 0.5, 1.0, 1.5, 2.0]))
    seeds = np.array([[0.8, 0.5, 0.3], [0.5, 0.2, 0.7]], np.float32)
    kw: Dict[str, Any] = dict(unsteady=True, step=0.1, start_time=0.25, vorticity=True, backend=backend)
    out = tetloc.trace(mesh, "v", seeds, **kw)
    t = out["IntegrationTime"]
    assert len(t) == 10 and t[0] == 0.25
    want = np.zeros((len(t), 3))
    want[:, 2] = 2 * (1 + t)
    assert out["Vorticity"].dtype == np.float64 and "Normals" not in out
    np.testing.assert_allclose(out["Vorticity"], want, rtol=0, atol=1e-6)
    np.testing.assert_allclose(out["AngularVelocity"], 0, atol=1e-6)
    np.testing.assert_allclose(out["Rotation"], 0, atol=1e-6)
    poly = tetloc.trace(mesh, "v", seeds, as_pyvista=True, **kw)
    for name in ("Vorticity", "AngularVelocity", "Rotation"):
        np.testing.assert_array_equal(poly.point_data[name], out[name])


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
def test_reinjected_pathlines(tmp_path, backend):
    """reinject_every=2: the seeds injected again at every second output time (ParaView's
    Force Reinjection Every NSteps), each injection's particles lines of their own that start
    at their injection time and follow the closed form from there; a seed outside is counted
    once an injection in the warning."""
    pvd = spin_series(tmp_path, [0.0, 0.5, 1.0, 1.5, 2.0])
    mesh = tetloc.read(pvd)
    seeds = np.array([[0.8, 0.5, 0.3], [0.5, 0.2, 0.7], [3.0, 0.5, 0.5]], np.float32)
    with pytest.warns(RuntimeWarning, match=r"trace: 2 of 6 particles make no line \(injected outside the mesh"):
        out = tetloc.trace(mesh, "v", seeds, unsteady=True, step=0.1, reinject_every=2, backend=backend)
    # Injected at 0.0 (5 points) and 1.0 (3 points).
    assert list(out["offsets"]) == [0, 5, 10, 13, 16]
    assert list(out["SeedIds"]) == [0, 1, 0, 1]
    t = out["IntegrationTime"]
    np.testing.assert_allclose(t, [0.0, 0.5, 1.0, 1.5, 2.0] * 2 + [1.0, 1.5, 2.0] * 2)
    t0 = np.repeat([0.0, 0.0, 1.0, 1.0], [5, 5, 3, 3])
    theta = (t - t0) + 0.5 * (t * t - t0 * t0)
    s = np.repeat(seeds[[0, 1, 0, 1]].astype(np.float64), [5, 5, 3, 3], axis=0) - [0.5, 0.5, 0.0]
    want = np.stack([0.5 + np.cos(theta) * s[:, 0] - np.sin(theta) * s[:, 1],
                     0.5 + np.sin(theta) * s[:, 0] + np.cos(theta) * s[:, 1], s[:, 2]], 1)
    assert np.abs(out["points"] - want).max() < 1.2e-3
    once = tetloc.trace(mesh, "v", seeds[:2], unsteady=True, step=0.1, backend=backend)
    np.testing.assert_array_equal(out["points"][:10], once["points"])
    # Each point's particle, as vtkParticlePathFilter writes it (ids start again each injection).
    sizes = [5, 5, 3, 3]
    np.testing.assert_array_equal(out["ParticleId"], np.repeat([0, 1, 0, 1], sizes))
    np.testing.assert_array_equal(out["InjectedPointId"], np.repeat([0, 1, 0, 1], sizes))
    assert out["InjectedPointId"].dtype == np.int64 and out["ParticleId"].dtype == np.int32
    np.testing.assert_array_equal(out["InjectionStepId"], np.repeat([0, 0, 2, 2], sizes))
    np.testing.assert_array_equal(out["ParticleAge"], (t - t0).astype(np.float32))
    # VTK's constant arrays, in its types (vtk_pathlines.py compare checks them against VTK's).
    for name, dtype in (("ErrorCode", np.int32), ("ParticleSourceId", np.int8)):
        assert out[name].dtype == dtype and out[name].shape == (16,) and not out[name].any(), name
    poly = tetloc.trace(mesh, "v", seeds[:2], unsteady=True, step=0.1, reinject_every=2, backend=backend, as_pyvista=True)
    for name in tetloc._ops.PARTICLE_ARRAYS:
        np.testing.assert_array_equal(poly.point_data[name], out[name])
    bad: Any
    for bad, error in ((-1, ValueError), (1.5, TypeError), (True, TypeError)):
        with pytest.raises(error, match="reinject_every"):
            tetloc.trace(mesh, "v", seeds, unsteady=True, reinject_every=bad, backend=backend)
    with pytest.raises(ValueError, match="reinject_every, streaklines and every_output_time apply to pathlines"):
        tetloc.trace(mesh, "v", seeds, reinject_every=1, backend=backend)


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
def test_streaklines(tmp_path, backend):
    """streaklines=True: per seed, its particles (injected at every output time) at the end
    time, oldest first and the seed itself last, with their ages; each point is the last point
    of that particle's pathline."""
    mesh = tetloc.read(spin_series(tmp_path, [0.0, 0.5, 1.0, 1.5, 2.0]))
    seeds = np.array([[0.8, 0.5, 0.3], [0.5, 0.2, 0.7]], np.float32)
    out = tetloc.trace(mesh, "v", seeds, unsteady=True, step=0.1, streaklines=True, backend=backend)
    assert "IntegrationTime" not in out
    assert list(out["offsets"]) == [0, 5, 10]
    assert list(out["SeedIds"]) == [0, 1]
    np.testing.assert_array_equal(out["ParticleAge"], [2.0, 1.5, 1.0, 0.5, 0.0] * 2)
    np.testing.assert_array_equal(out["points"][[4, 9]], seeds)
    # Each point's particle: seed k's injected at output time j has ParticleId k.
    np.testing.assert_array_equal(out["ParticleId"], np.repeat([0, 1], 5))
    np.testing.assert_array_equal(out["InjectionStepId"], [0, 1, 2, 3, 4] * 2)
    assert out["ParticleAge"].dtype == np.float64, "the streaks' time array is their age"
    paths = tetloc.trace(mesh, "v", seeds, unsteady=True, step=0.1, reinject_every=1, backend=backend)
    # Pathlines in injection order (0, 0.5, 1, 1.5), each injection in seed order: their last
    # points are the streaks' oldest-first points.
    last = paths["points"][paths["offsets"][1:] - 1].reshape(4, 2, 3)
    np.testing.assert_array_equal(out["points"].reshape(2, 5, 3)[:, :4], last.transpose(1, 0, 2))
    outside = np.vstack([seeds, [[3.0, 0.5, 0.5]]]).astype(np.float32)
    with pytest.warns(RuntimeWarning, match=r"trace: 1 of 3 seeds make no streakline \(fewer than two"):
        tetloc.trace(mesh, "v", outside, unsteady=True, step=0.1, streaklines=True, backend=backend)
    poly = tetloc.trace(mesh, "v", seeds, unsteady=True, step=0.1, streaklines=True, backend=backend,
                        as_pyvista=True)
    np.testing.assert_array_equal(poly.point_data["ParticleAge"], out["ParticleAge"])
    assert poly.n_lines == 2


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
def test_every_output_time(tmp_path, backend):
    """every_output_time=True: (time, lines) at each output time after the start, each equal
    to the run that ends there (pathlines reinjected, with a particle that leaves the cube
    between output times; streaklines; pyvista), the last one the run's own output."""
    mesh = tetloc.read(spin_series(tmp_path, [0.0, 0.5, 1.0, 1.5, 2.0]))
    # The last seed's circle (radius 0.52, from 20 degrees) leaves the unit cube through y = 1
    # at 74 degrees: at t = 0.69 from 0, between the first two output times.
    seeds = np.array([[0.8, 0.5, 0.3], [0.5, 0.2, 0.7], [0.988, 0.678, 0.5]], np.float32)
    for kind in ({"reinject_every": 2}, {"streaklines": True}):
        opts: Dict[str, Any] = dict(unsteady=True, step=0.1, start_time=0.25, backend=backend, **kind)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            frames = tetloc.trace(mesh, "v", seeds, every_output_time=True, **opts)
            assert [t for t, _ in frames] == [0.5, 1.0, 1.5, 2.0]
            for t, lines in frames:
                alone = tetloc.trace(mesh, "v", seeds, end_time=t, **opts)
                assert lines.keys() == alone.keys(), (kind, t)
                for name in alone:
                    np.testing.assert_array_equal(lines[name], alone[name], err_msg=f"{kind} at {t}: {name}")
            polys = tetloc.trace(mesh, "v", seeds, every_output_time=True, as_pyvista=True, **opts)
        assert [p.n_lines for _, p in polys] == [len(lines["offsets"]) - 1 for _, lines in frames]
    paths = tetloc.trace(mesh, "v", seeds, every_output_time=True, unsteady=True, step=0.1, backend=backend)
    gone = [int((lines["ReasonForTermination"] == 1).sum()) for _, lines in paths]
    assert gone[0] < gone[-1], gone  # cut at first (reason 7), gone by the end (1)
    with pytest.raises(ValueError, match="every_output_time apply to pathlines"):
        tetloc.trace(mesh, "v", seeds, every_output_time=True, backend=backend)


def test_pathlines_beyond_memory_are_a_memory_error(tmp_path):
    """3M seeds injected again at every one of 40 output times would record 2.6e9 points
    (hundreds of GB): a MemoryError before any step is read. The run held every particle to
    the end unchecked, until an allocation failed and aborted the interpreter."""
    mesh = tetloc.read(spin_series(tmp_path, [0.05 * k for k in range(41)]))
    seeds = np.full((3_000_000, 3), 0.5, np.float32)
    with pytest.raises(MemoryError, match=r"120000000 particles over 40 output times .* GB of memory"):
        tetloc.trace(mesh, "v", seeds, unsteady=True, reinject_every=1, backend="cpu")


def test_pathline_bad_inputs(tmp_path, data_dir):
    with pytest.raises(ValueError, match=r"delaunay_s.vtu.*single snapshot"):
        tetloc.trace(tetloc.read(data_dir / "delaunay_s.vtu"), "v", np.zeros((1, 3), np.float32), unsteady=True)
    mesh = tetloc.read(spin_series(tmp_path, [0.0, 1.0]))
    with pytest.raises(ValueError, match=r"the start time -1(\.0)? is outside the time steps of .*spin.pvd \(0 to 1\)"):
        tetloc.trace(mesh, "v", np.full((1, 3), 0.5, np.float32), unsteady=True, start_time=-1.0)
    with pytest.raises(ValueError, match=r"end time 2(\.0)? is outside"):
        tetloc.trace(mesh, "v", np.full((1, 3), 0.5, np.float32), unsteady=True, end_time=2.0)


def test_time_steps_example(time_dir, tmp_path):
    """python/examples/time_steps.py: every step of a series at probes, saved as .npy."""
    import subprocess
    import sys

    example = pathlib.Path(__file__).resolve().parents[1] / "examples" / "time_steps.py"
    out = tmp_path / "history.npy"
    run = subprocess.run(
        [sys.executable, str(example), str(time_dir / "part_s.e"), "f", "--points", "500", "--backend", "cpu",
         "--out", str(out)],
        capture_output=True, text=True, timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert "6 steps" in run.stdout and "on cpu" in run.stdout, run.stdout
    history = np.load(out)
    assert history.shape == (6, 500) and np.isfinite(history).any(axis=1).all()
