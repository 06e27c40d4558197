"""tetloc.resample_to_image, tetloc.probe and tetloc.trace: known answers on a linear field,
the same answers as the CLI and as VTK itself (vtkResampleToImage, vtkResampleWithDataSet,
vtkStreamTracer), pyvista in and out, bad arguments, and every backend against cpu."""

from __future__ import annotations

import subprocess
import sys
from typing import Any, Dict

import numpy as np
import pytest
from conftest import in_ci, kuhn_grid, missing

import tetloc


def need(module: str):
    """The module, or a skip (a failure in CI, where the test command installs it)."""
    try:
        return __import__(module)
    except ImportError:
        missing(f"{module} is not installed")


@pytest.fixture(scope="module")
def swirl_mesh() -> tetloc.Mesh:
    """A 6-cube Kuhn grid on [0, 1]^3 with f = x + 2y + 3z and a swirl v that lines leave."""
    points, cells = kuhn_grid(6, 1.0 / 6.0)
    x, y, z = points.T
    v = np.stack([-(y - 0.5) + 0.1, (x - 0.5) + 0.05 * z, 0.2 - 0.1 * x], axis=1)
    return tetloc.Mesh(points, cells, point_data={"f": x + 2 * y + 3 * z, "v": v}, cell_data={"c": np.arange(len(cells))})


# --- resample_to_image


def test_resample_reproduces_a_linear_field(swirl_mesh):
    img = tetloc.resample_to_image(swirl_mesh, "f", dims=(5, 4, 3), bounds=(0, 1.25, 0, 1, 0, 1), backend="cpu")
    assert img.shape == (3, 4, 5) and img.dtype == np.float32
    z, y, x = np.meshgrid(np.linspace(0, 1, 3), np.linspace(0, 1, 4), np.linspace(0, 1.25, 5), indexing="ij")
    inside = x <= 1
    np.testing.assert_allclose(img[inside], (x + 2 * y + 3 * z)[inside], atol=1e-5)
    assert np.isnan(img[~inside]).all()
    all_fields = tetloc.resample_to_image(swirl_mesh, dims=(5, 4, 3), bounds=(0, 1.25, 0, 1, 0, 1), backend="cpu")
    assert set(all_fields) == {"f", "v", "c", "vtkValidPointMask"}
    assert all_fields["v"].shape == (3, 4, 5, 3)
    np.testing.assert_array_equal(all_fields["vtkValidPointMask"], inside.astype(np.uint8))
    np.testing.assert_array_equal(all_fields["f"], img)


def test_resample_matches_the_cli_and_vtk(cli, data_dir, tmp_path):
    mesh_path = data_dir / "torus_s.vtu"
    ours = tetloc.resample_to_image(tetloc.read(mesh_path), "f", dims=(23, 19, 11), backend="cpu")
    out = tmp_path / "f.npy"
    subprocess.run([cli, "resample", str(mesh_path), "--dims", "23,19,11", "--field", "f", "-o", str(out),
                    "--backend", "cpu", "--quiet"], check=True)
    np.testing.assert_array_equal(np.load(out), ours)
    vtk = need("vtk")
    from vtk.util.numpy_support import vtk_to_numpy

    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(mesh_path))
    f = vtk.vtkResampleToImage()
    f.SetInputConnection(r.GetOutputPort())
    f.SetUseInputBounds(True)
    f.SetSamplingDimensions(23, 19, 11)
    f.Update()
    pd = f.GetOutput().GetPointData()
    mask = vtk_to_numpy(pd.GetArray("vtkValidPointMask")).reshape(ours.shape)
    theirs = vtk_to_numpy(pd.GetArray("f")).reshape(ours.shape)
    both = (mask == 1) & ~np.isnan(ours)
    # VTK's tolerant cell search takes a few points just outside as inside (see ops.rs).
    assert (mask != ~np.isnan(ours)).sum() <= mask.size // 200
    close = np.isclose(ours[both], theirs[both], rtol=1e-5, atol=1e-5)
    assert close.mean() > 0.99


def test_a_deferred_cpu_locator_answers_as_one_built_now(grid_mesh):
    """deferred=True builds the search on first need: the same ids and values as a locator
    built up front, for a grid (rasterized, the Kuhn grid's faces left to the search) and
    for points."""
    eager = tetloc.Locator(grid_mesh, backend="cpu")
    lazy = tetloc.Locator(grid_mesh, backend="cpu", deferred=True)
    for dims, bounds in [((9, 7, 5), None), ((13, 13, 13), (0, 6, 0, 6, 0, 6))]:
        a = tetloc.resample_to_image(eager, "f", dims=dims, bounds=bounds)
        b = tetloc.resample_to_image(lazy, "f", dims=dims, bounds=bounds)
        np.testing.assert_array_equal(a, b)
    pts = np.random.default_rng(3).uniform(-0.5, 6.5, (5000, 3)).astype(np.float32)
    np.testing.assert_array_equal(eager.locate(pts), tetloc.Locator(grid_mesh, backend="cpu", deferred=True).locate(pts))


def test_resample_to_pyvista(swirl_mesh):
    pv = need("pyvista")
    img = tetloc.resample_to_image(swirl_mesh, ["f", "v"], dims=(4, 4, 4), backend="cpu", as_pyvista=True)
    assert isinstance(img, pv.ImageData) and img.dimensions == (4, 4, 4)
    assert set(img.point_data.keys()) == {"f", "v", "vtkValidPointMask"}
    assert img.point_data["v"].shape == (64, 3)
    # A pyvista mesh in, pyvista out; the grid spans its bounds.
    grid = swirl_mesh.to_pyvista()
    img2 = tetloc.resample_to_image(grid, "f", dims=(4, 4, 4), backend="cpu")
    assert isinstance(img2, pv.ImageData)
    np.testing.assert_allclose(img2.point_data["f"], img.point_data["f"], atol=1e-6)
    pts = np.asarray(img2.points)
    np.testing.assert_allclose(img2.point_data["f"], pts @ [1, 2, 3], atol=1e-4)


def test_resample_bad_arguments(swirl_mesh):
    with pytest.raises(ValueError, match="at least 1"):
        tetloc.resample_to_image(swirl_mesh, "f", dims=(4, 0, 4), backend="cpu")
    with pytest.raises(ValueError, match="'nope'"):
        tetloc.resample_to_image(swirl_mesh, "nope", dims=(4, 4, 4), backend="cpu")
    with pytest.raises(ValueError, match="six numbers"):
        tetloc.resample_to_image(swirl_mesh, "f", dims=(4, 4, 4), bounds=(0, 1), backend="cpu")
    with pytest.raises(ValueError, match="not finite"):
        tetloc.resample_to_image(swirl_mesh, "f", dims=(4, 4, 4), bounds=(1, 0, 0, 1, 0, 1), backend="cpu")
    with pytest.raises(TypeError, match="tetloc.Mesh"):
        tetloc.resample_to_image("mesh.vtu", "f")


# --- probe


def test_probe_points_and_meshes(swirl_mesh):
    rng = np.random.default_rng(5)
    pts = rng.uniform(-0.2, 1.2, size=(2000, 3))
    res = tetloc.probe(swirl_mesh, pts, backend="cpu")
    inside = ((pts >= 0) & (pts <= 1)).all(axis=1)
    np.testing.assert_array_equal(res["vtkValidPointMask"], inside.astype(np.uint8))
    np.testing.assert_allclose(res["f"][inside], (pts @ [1, 2, 3])[inside], atol=1e-4)
    assert np.isnan(res["v"][~inside]).all() and res["v"].shape == (2000, 3)
    loc = tetloc.Locator(swirl_mesh, backend="cpu")
    np.testing.assert_array_equal(tetloc.probe(loc, pts, "f"), res["f"])
    # float64 points keep their precision and a field of float64 data comes back float64,
    # as Locator.sample gives it; float32 points are probed as they are.
    assert swirl_mesh.field("f").dtype == np.float64 and res["f"].dtype == np.float64
    np.testing.assert_array_equal(res["f"], loc.sample(pts, "f"))
    p32 = pts.astype(np.float32)
    np.testing.assert_array_equal(tetloc.probe(loc, p32, "f"), loc.sample(p32.astype(np.float64), "f"))
    # A mesh as target: its vertices.
    onto = tetloc.probe(swirl_mesh, swirl_mesh, "f", backend="cpu")
    np.testing.assert_allclose(onto, swirl_mesh.field("f"), atol=1e-5)


def test_probe_matches_the_cli(cli, data_dir, tmp_path):
    pv = need("pyvista")
    mesh_path, pts_path = data_dir / "torus_s.vtu", data_dir / "torus_s.bbox.points.bin"
    pts = np.fromfile(pts_path, dtype="<f4").reshape(-1, 3)
    ours = tetloc.probe(tetloc.read(mesh_path), pts, backend="cpu", as_pyvista=True)
    out = tmp_path / "p.vtp"
    subprocess.run([cli, "probe", str(mesh_path), str(pts_path), "-o", str(out), "--backend", "cpu", "--quiet"],
                   check=True)
    theirs = pv.read(out)
    # Both keep the f64 field as float64 (as VTK's probe keeps the type).
    for name in ("f", "vtkValidPointMask"):
        ours_a, theirs_a = np.asarray(ours.point_data[name]), np.asarray(theirs.point_data[name])
        assert ours_a.dtype == theirs_a.dtype, name
        np.testing.assert_array_equal(ours_a, theirs_a)


def test_probe_pyvista_target_keeps_its_data(swirl_mesh):
    pv = need("pyvista")
    target = pv.ImageData(dimensions=(4, 4, 4), spacing=(0.4, 0.4, 0.4), origin=(-0.1, -0.1, -0.1))
    target.point_data["mine"] = np.arange(64.0)
    out = tetloc.probe(swirl_mesh, target, ["f"], backend="cpu")
    assert isinstance(out, pv.ImageData)
    assert set(out.point_data.keys()) == {"mine", "f", "vtkValidPointMask"}
    assert "f" not in target.point_data  # a copy
    valid = out.point_data["vtkValidPointMask"] == 1
    np.testing.assert_allclose(out.point_data["f"][valid], (np.asarray(out.points) @ [1, 2, 3])[valid], atol=1e-4)


def test_probe_bad_arguments(swirl_mesh):
    with pytest.raises(ValueError, match=r"\(K, 3\)"):
        tetloc.probe(swirl_mesh, np.zeros((4, 2)), backend="cpu")
    with pytest.raises(ValueError, match="'nope'"):
        tetloc.probe(swirl_mesh, np.zeros((4, 3)), "nope", backend="cpu")
    with pytest.raises(ValueError, match="unknown"):
        tetloc.probe(swirl_mesh, np.zeros((4, 3)), backend="warp-drive")


# --- trace


def seeds():
    s = np.array([[0.3, 0.3, 0.3], [0.6, 0.4, 0.5], [0.5, 0.7, 0.2], [2.0, 0.5, 0.5]], dtype=np.float32)
    return s


def lines_of(t):
    return [t["points"][a:b] for a, b in zip(t["offsets"][:-1], t["offsets"][1:])]


def test_trace_lines(swirl_mesh):
    with pytest.warns(RuntimeWarning, match=r"trace: 2 of 8 lines have no step inside the mesh"):
        t = tetloc.trace(swirl_mesh, "v", seeds(), step=0.01, max_steps=500, direction="both", backend="cpu")
    # The seed outside gives no line (counted in the warning); the others one each way.
    assert len(t["offsets"]) == 7 and list(t["SeedIds"]) == [0, 1, 2, 0, 1, 2]
    assert t["points"].dtype == np.float32 and t["IntegrationTime"].dtype == np.float64
    assert set(t) >= {"points", "offsets", "IntegrationTime", "ReasonForTermination", "SeedIds", "f", "v"}
    assert t["v"].shape == (len(t["points"]), 3)
    for line, seed in zip(lines_of(t), seeds()[[0, 1, 2, 0, 1, 2]]):
        np.testing.assert_array_equal(line[0], seed)
        steps = np.linalg.norm(np.diff(line.astype(np.float64), axis=0), axis=1)
        assert steps.max() <= 0.01 + 1e-6
    assert set(t["ReasonForTermination"]) <= {1, 5}
    assert tetloc.REASONS[1] == "OUT_OF_DOMAIN"
    times = np.split(t["IntegrationTime"], t["offsets"][1:-1])
    assert all(np.all(np.diff(tt) > 0) for tt in times[:3]) and all(np.all(np.diff(tt) < 0) for tt in times[3:])


def test_trace_limits_and_integrators(swirl_mesh):
    for integrator in ("rk4", "rk45", "cash-karp"):
        t = tetloc.trace(swirl_mesh, "v", seeds()[:1], step=0.01, max_time=0.5, integrator=integrator, backend="cpu")
        assert list(t["ReasonForTermination"]) == [7], integrator
        assert t["IntegrationTime"][-1] == pytest.approx(0.5, abs=1e-12)
        t = tetloc.trace(swirl_mesh, "v", seeds()[:1], step=0.01, max_length=0.3, integrator=integrator,
                         backend="cpu")
        assert list(t["ReasonForTermination"]) == [4], integrator
        # The chords of an arc of curvature k (here up to 5) are shorter by h^2 k^2 / 24.
        chords = np.linalg.norm(np.diff(t["points"].astype(np.float64), axis=0), axis=1).sum()
        assert 0.3 * (1 - 0.01**2 * 25 / 24) - 1e-6 <= chords <= 0.3 + 1e-6, integrator


def test_trace_matches_the_cli(cli, swirl_mesh, tmp_path):
    pv = need("pyvista")
    mesh_path, seeds_path, out = tmp_path / "swirl.vtu", tmp_path / "seeds.bin", tmp_path / "lines.vtp"
    swirl_mesh.to_pyvista().save(mesh_path)
    seeds().tofile(seeds_path)
    subprocess.run([cli, "trace", str(mesh_path), "--vector", "v", "--seeds", str(seeds_path), "-o", str(out),
                    "--step", "0.01", "--integrator", "rk45", "--backend", "cpu", "--quiet"], check=True)
    theirs = pv.read(out)
    with pytest.warns(RuntimeWarning, match=r"trace: 1 of 4 lines"):  # as the CLI warns
        ours = tetloc.trace(tetloc.read(mesh_path), "v", seeds(), step=0.01, integrator="rk45", backend="cpu",
                            as_pyvista=True)
    assert isinstance(ours, pv.PolyData) and ours.n_lines == theirs.n_lines == 3
    np.testing.assert_array_equal(np.asarray(ours.points), np.asarray(theirs.points))
    for name in ("IntegrationTime", "f", "v"):
        np.testing.assert_array_equal(np.asarray(ours.point_data[name]), np.asarray(theirs.point_data[name]))
    for name in ("ReasonForTermination", "SeedIds"):
        np.testing.assert_array_equal(np.asarray(ours.cell_data[name]), np.asarray(theirs.cell_data[name]))


def vtk_rk4_tracer(vtk, grid, seeds, step: float, max_steps: int):
    """vtkStreamTracer on `grid`'s point vector ``v`` from `seeds`: RK4, steps in length units."""
    t = vtk.vtkStreamTracer()
    t.SetInputData(grid)
    src = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    for p in seeds:
        pts.InsertNextPoint(*map(float, p))
    src.SetPoints(pts)
    t.SetSourceData(src)
    t.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "v")
    t.SetIntegratorTypeToRungeKutta4()
    t.SetIntegrationStepUnit(vtk.vtkStreamTracer.LENGTH_UNIT)
    t.SetInitialIntegrationStep(step)
    t.SetMaximumNumberOfSteps(max_steps)
    return t


def test_trace_matches_vtk(swirl_mesh):
    vtk = need("vtk")
    need("pyvista")
    from vtk.util.numpy_support import vtk_to_numpy

    grid = swirl_mesh.to_pyvista()
    t = vtk_rk4_tracer(vtk, grid, seeds(), 0.01, 500)
    t.SetMaximumPropagation(1e30)
    t.SetComputeVorticity(False)
    t.Update()
    theirs = t.GetOutput()
    with pytest.warns(RuntimeWarning, match=r"trace: 1 of 4 lines"):
        ours = tetloc.trace(grid, "v", seeds(), step=0.01, max_steps=500, backend="cpu")
    assert ours.n_lines == theirs.GetNumberOfLines() == 3
    np.testing.assert_array_equal(np.asarray(ours.cell_data["ReasonForTermination"]),
                                  vtk_to_numpy(theirs.GetCellData().GetArray("ReasonForTermination")))
    their_offsets = vtk_to_numpy(theirs.GetLines().GetOffsetsArray())
    their_points = vtk_to_numpy(theirs.GetPoints().GetData())[vtk_to_numpy(theirs.GetLines().GetConnectivityArray())]
    our_offsets = ours.lines.reshape(-1)  # [n, ids..., n, ids...]
    ours_lines, i = [], 0
    while i < len(our_offsets):
        n = our_offsets[i]
        ours_lines.append(np.asarray(ours.points)[our_offsets[i + 1:i + 1 + n]])
        i += 1 + n
    for l, mine in enumerate(ours_lines):
        vtk_line = their_points[their_offsets[l]:their_offsets[l + 1]]
        # At the boundary VTK's tolerant cell search may take one more step.
        assert abs(len(mine) - len(vtk_line)) <= 1, l
        n = min(len(mine), len(vtk_line))
        np.testing.assert_allclose(mine[:n], vtk_line[:n], atol=1e-4)


def test_trace_bad_arguments(swirl_mesh):
    with pytest.raises(ValueError, match="'nope'"):
        tetloc.trace(swirl_mesh, "nope", seeds(), backend="cpu")
    with pytest.raises(ValueError, match="3 components"):
        tetloc.trace(swirl_mesh, "f", seeds(), backend="cpu")
    with pytest.raises(ValueError, match="direction"):
        tetloc.trace(swirl_mesh, "v", seeds(), direction="sideways", backend="cpu")
    with pytest.raises(ValueError, match="integrator"):
        tetloc.trace(swirl_mesh, "v", seeds(), integrator="euler", backend="cpu")
    with pytest.raises(ValueError, match="step"):
        tetloc.trace(swirl_mesh, "v", seeds(), step=-1.0, backend="cpu")
    with pytest.raises(ValueError, match="min <= max"):
        tetloc.trace(swirl_mesh, "v", seeds(), integrator="rk45", min_step=0.1, max_step=0.01, backend="cpu")
    with pytest.raises(ValueError, match=r"\(K, 3\)"):
        tetloc.trace(swirl_mesh, "v", np.zeros((3, 2)), backend="cpu")
    # Seeds all outside: no lines, no error, a warning.
    with pytest.warns(RuntimeWarning, match=r"trace: 1 of 1 lines have no step inside the mesh"):
        t = tetloc.trace(swirl_mesh, "v", [[5.0, 5.0, 5.0]], backend="cpu")
    assert len(t["points"]) == 0 and list(t["offsets"]) == [0]


# --- every backend


GPU_BACKENDS = ["soft-bvh", "rt-bvh", "rt-rep-faces", "rt-shared-faces"]


@pytest.mark.parametrize("backend", GPU_BACKENDS)
def test_every_backend_agrees_with_cpu(vulkan, swirl_mesh, backend):
    """Resample and probe: the same mask but within rounding of the boundary, values within
    1e-5 relative. Trace (step-synchronous on the GPU): the same lines, reasons and point
    counts, points within 1e-5 of the domain (float32 sampling on the GPU vs the CPU's
    interpolation: ~1e-7 per lookup, over a few hundred steps)."""
    loc = tetloc.Locator(swirl_mesh, backend=backend)
    cpu = tetloc.Locator(swirl_mesh, backend="cpu")
    a = tetloc.resample_to_image(loc, dims=(9, 8, 7), bounds=(-0.1, 1.1, -0.1, 1.1, -0.1, 1.1))
    b = tetloc.resample_to_image(cpu, dims=(9, 8, 7), bounds=(-0.1, 1.1, -0.1, 1.1, -0.1, 1.1))
    rng = np.random.default_rng(7)
    pts = rng.uniform(-0.1, 1.1, size=(3000, 3)).astype(np.float32)
    p, q = tetloc.probe(loc, pts), tetloc.probe(cpu, pts)
    # Grid points on shared faces (x = 0.5 here) may take either tet's cell value: the cell
    # field is compared at the random points only.
    for ours, theirs, names in ((a, b, ("f", "v")), (p, q, ("f", "v", "c"))):
        differ = ours["vtkValidPointMask"] != theirs["vtkValidPointMask"]
        assert differ.sum() <= 2, f"{backend}: masks differ at {differ.sum()} points"
        both = (ours["vtkValidPointMask"] == 1) & ~differ
        for name in names:
            np.testing.assert_allclose(ours[name][both], theirs[name][both], rtol=1e-5, atol=1e-6, err_msg=name)
    with pytest.warns(RuntimeWarning, match=r"trace: 2 of 8 lines"):  # the seed outside, both ways
        t_gpu = tetloc.trace(loc, "v", seeds(), step=0.01, max_steps=300, direction="both")
    with pytest.warns(RuntimeWarning, match=r"trace: 2 of 8 lines"):
        t_cpu = tetloc.trace(swirl_mesh, "v", seeds(), step=0.01, max_steps=300, direction="both", backend="cpu")
    np.testing.assert_array_equal(t_gpu["offsets"], t_cpu["offsets"])
    np.testing.assert_array_equal(t_gpu["ReasonForTermination"], t_cpu["ReasonForTermination"])
    np.testing.assert_array_equal(t_gpu["SeedIds"], t_cpu["SeedIds"])
    np.testing.assert_allclose(t_gpu["points"], t_cpu["points"], atol=1e-5)
    assert not in_ci() or tetloc._tetloc.validation_errors() == 0


@pytest.mark.parametrize("shape, size", [("fusion", "--tets=20k"), ("jets-hex", "--cells=3000")])
def test_trace_vorticity_matches_vtk(cli, tmp_path, shape, size):
    """``vorticity=True`` gives vtkStreamTracer's ComputeVorticity arrays. The vorticity is the
    curl in the cell holding each point: wherever VTK's FindCell returns a cell that holds the
    point strictly, it is the curl of VTK's own ``vtkCell.Derivatives`` there. The tracer's
    arrays agree at most points; where they differ, VTK's tracer took a neighbouring cell,
    since its cell search accepts points just outside a cell and the gradient jumps across
    faces. On lines where every vorticity agrees, AngularVelocity, Rotation and Normals agree
    too, within the float32 rounding of the line points. The CLI's ``--vorticity`` writes the
    same arrays."""
    vtk = need("vtk")
    pv = need("pyvista")
    from vtk.util.numpy_support import vtk_to_numpy

    mesh_path = tmp_path / "m.vtu"
    subprocess.run([cli, "gen", shape, size, "--vector", "-o", str(mesh_path), "--quiet"], check=True)
    grid = pv.read(mesh_path)
    centres = np.asarray(grid.cell_centers().points, dtype=np.float32)
    seeds = centres[:: max(1, len(centres) // 25)]
    step = 0.1 * float(np.mean(grid.compute_cell_sizes(length=False, area=False).cell_data["Volume"]) ** (1 / 3))
    t = vtk_rk4_tracer(vtk, grid, seeds, step, 150)
    t.SetMaximumPropagation(1e30)
    t.SetIntegrationDirectionToBoth()
    t.SetComputeVorticity(True)
    t.Update()
    theirs = t.GetOutput()
    ours = tetloc.trace(tetloc.read(mesh_path), "v", seeds, step=step, max_steps=150, direction="both",
                        backend="cpu", vorticity=True)
    theirs_offsets = vtk_to_numpy(theirs.GetLines().GetOffsetsArray())
    np.testing.assert_array_equal(ours["offsets"], theirs_offsets)
    points = ours["points"].astype(np.float64)
    np.testing.assert_allclose(points, vtk_to_numpy(theirs.GetPoints().GetData()), atol=1e-5)
    theirs_arrays = {name: vtk_to_numpy(theirs.GetPointData().GetArray(name))
                     for name in ("Vorticity", "AngularVelocity", "Rotation", "Normals")}
    for name, values in theirs_arrays.items():
        assert ours[name].dtype == np.float64 and ours[name].shape == values.shape, name

    vertex_v = vtk_to_numpy(grid.GetPointData().GetArray("v")).astype(np.float64)
    scale = np.abs(theirs_arrays["Vorticity"]).max()
    held = 0
    for p, mine in zip(points, ours["Vorticity"]):
        weights, pcoords = [0.0] * 8, [0.0] * 3
        c = grid.FindCell(p, None, 0, 0.0, vtk.reference(0), pcoords, weights)
        cell = grid.GetCell(c)
        closest, d2, sub = [0.0] * 3, vtk.reference(0.0), vtk.reference(0)
        inside = cell.EvaluatePosition(p, closest, sub, pcoords, d2, weights)
        n = cell.GetNumberOfPoints()
        # Distances to the faces in parametric units: a tet's barycentrics, a hex's pcoords.
        faces = [1 - sum(pcoords)] + pcoords if n == 4 else pcoords + [1 - x for x in pcoords]
        if inside != 1 or min(faces) <= 1e-6:
            continue  # on or near a face: either neighbour's gradient is the curl there
        ids = [cell.GetPointId(k) for k in range(n)]
        derivs = [0.0] * 9
        cell.Derivatives(0, pcoords, vertex_v[ids].ravel().tolist(), 3, derivs)
        d = np.array(derivs).reshape(3, 3)  # d[c][k] = dv_c/dx_k
        curl = [d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]]
        np.testing.assert_allclose(mine, curl, rtol=0, atol=1e-9 * scale)
        held += 1
    assert held > 0.8 * len(points), (held, len(points))

    same = np.abs(ours["Vorticity"] - theirs_arrays["Vorticity"]).max(axis=1) <= 1e-9 * scale
    assert same.mean() > 0.9, same.mean()
    clean = np.zeros(len(points), bool)
    for a, b in zip(theirs_offsets[:-1], theirs_offsets[1:]):
        clean[a:b] = same[a:b].all()
    assert clean.sum() > 0.3 * len(points), clean.sum()
    for name, tol in (("AngularVelocity", 1e-5), ("Rotation", 1e-5), ("Normals", 1e-3)):
        their = theirs_arrays[name]
        np.testing.assert_allclose(ours[name][clean], their[clean], rtol=0, atol=tol * max(1.0, np.abs(their).max()),
                                   err_msg=name)

    out = tmp_path / "lines.vtp"
    seeds_path = tmp_path / "seeds.npy"
    np.save(seeds_path, seeds)
    subprocess.run([cli, "trace", str(mesh_path), "--vector", "v", "--seeds", str(seeds_path), "--step", repr(step),
                    "--max-steps", "150", "--direction", "both", "--backend", "cpu", "--vorticity", "-o", str(out),
                    "--quiet"], check=True)
    written = pv.read(out)
    for name in theirs_arrays:
        np.testing.assert_array_equal(np.asarray(written.point_data[name]), ours[name], err_msg=name)


def test_probe_keeps_every_field_at_any_precision():
    """Hostile test: probing float32 fields at float32 points (or at float64 points that float32
    holds, such as points on faces) returned the mask alone, every field dropped."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], np.float64)
    for dtype in (np.float32, np.float64):
        mesh = tetloc.Mesh(pts, np.array([[0, 1, 2, 3], [1, 2, 3, 4]]), point_data={"f": (pts @ [1, 2, 3]).astype(dtype)})
        loc = tetloc.Locator(mesh, backend="cpu")
        for target in (np.array([[0.5, 0.5, 0.0]]), np.array([[0.1, 0.1, 0.1]], np.float32), mesh, np.zeros((0, 3))):
            got = tetloc.probe(mesh, target, backend="cpu")
            assert set(got) == {"f", "vtkValidPointMask"}, (dtype, target)
            at = mesh.points64 if isinstance(target, tetloc.Mesh) else np.asarray(target, np.float64)
            np.testing.assert_allclose(got["f"], loc.sample(at, "f"), rtol=1e-6)
            np.testing.assert_array_equal(tetloc.probe(mesh, target, "f", backend="cpu"), got["f"])


def test_big_endian_float64_points_keep_their_digits():
    """'>f8' points are float64: located and sampled as '<f8' ones, not rounded to float32."""
    pts = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 1, 0], [0.1, 0, 1], [1, 0, 0]], np.float64)
    mesh = tetloc.Mesh(pts, np.array([[0, 1, 2, 3], [1, 4, 2, 3]]), point_data={"f": pts[:, 0] * 3})
    loc = tetloc.Locator(mesh, backend="cpu")
    near = np.array([[0.1 - 1e-9, 0.2, 0.2], [0.1 + 1e-9, 0.2, 0.2]])
    ids = loc.locate(near)
    assert list(ids) == [0, 1]
    np.testing.assert_array_equal(loc.locate(near.astype(">f8")), ids)
    np.testing.assert_array_equal(loc.sample(near.astype(">f8"), "f"), loc.sample(near, "f"))
    assert loc.sample(near.astype(">f8"), "f").dtype == np.float64
    np.testing.assert_array_equal(tetloc.probe(mesh, near.astype(">f8"), "f", backend="cpu"),
                                  tetloc.probe(mesh, near, "f", backend="cpu"))
    big = tetloc.Mesh(pts.astype(">f8"), np.array([[0, 1, 2, 3], [1, 4, 2, 3]]), point_data={"f": (pts[:, 0] * 3).astype(">f8")})
    np.testing.assert_array_equal(big.points64, mesh.points64)
    assert big.field("f").dtype == np.float64


@pytest.mark.parametrize("backend", ["cpu", "soft-bvh"])
def test_resample_far_from_the_origin_samples_the_images_points(request, backend):
    """On a mesh far from the origin (float64 coordinates), each image point's mask and value
    are those of locating that point (origin + index x spacing, in float64, as VTK lays the
    image), not of its float32 rounding, which at 4e6 is a quarter of a metre away: on the CPU
    and on a GPU kernel alike."""
    if backend != "cpu":
        request.getfixturevalue("vulkan")
    points, cells = kuhn_grid(5, 40.0)
    rng = np.random.default_rng(3)
    points = points + rng.uniform(-6, 6, points.shape) * (np.abs(points % 200) > 1e-9)  # the box's faces stay flat
    far = points + [512345.0, 4123456.0, 39.0]
    mesh = tetloc.Mesh(far, cells, point_data={"f": (points @ [1, 2, 3]) / 600})
    loc = tetloc.Locator(mesh, backend=backend)
    dims = (23, 19, 17)
    lo, hi = far.min(axis=0) - 3, far.max(axis=0) + 3
    img = tetloc.resample_to_image(loc, ["f"], dims=dims, bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
    axes = [lo[k] + np.arange(dims[k]) * ((hi[k] - lo[k]) / (dims[k] - 1)) for k in range(3)]  # as VTK lays them
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    g = np.stack([x, y, z], -1).reshape(-1, 3)
    cpu = tetloc.Locator(mesh, backend="cpu")
    ids = cpu.locate(g)
    np.testing.assert_array_equal(img["vtkValidPointMask"].ravel(), (ids >= 0).astype(np.uint8))
    inside = ids >= 0
    np.testing.assert_allclose(img["f"].ravel()[inside], cpu.sample(g, "f")[inside], rtol=0, atol=1e-5)
    # The float32 points differ: some grid points change cell there.
    assert (cpu.locate(g.astype(np.float32).astype(np.float64)) != ids).any()


def test_resample_beyond_memory_is_refused(swirl_mesh):
    with pytest.raises(MemoryError, match="dims"):
        tetloc.resample_to_image(swirl_mesh, "f", dims=(100000, 100000, 100000), backend="cpu")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS as Linux counts it")
def test_a_process_memory_limit_is_a_memory_error_not_a_crash():
    """Under an address-space limit (``ulimit -v``, as batch systems set; a cgroup's limit is
    read the same way) an image that the machine could hold but the process cannot is a
    MemoryError. The check compared with the machine's free memory alone, so the allocation
    was tried and failed, and that aborts the interpreter."""
    script = """
import resource, numpy as np, tetloc
vm = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmSize:"))
points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
mesh = tetloc.Mesh(points, np.array([[0, 1, 2, 3]]), point_data={"f": points[:, 0]})
resource.setrlimit(resource.RLIMIT_AS, (vm + (1 << 30), resource.RLIM_INFINITY))
try:
    tetloc.resample_to_image(mesh, "f", dims=(1000, 1000, 600), backend="cpu")
except MemoryError as e:
    print("MemoryError:", e)
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "MemoryError: dims" in run.stdout and "GB of memory, " in run.stdout, run.stdout


@pytest.mark.parametrize("arg", ["max_steps", "reinject_every"])
def test_trace_counts_are_whole_numbers(swirl_mesh, arg):
    """A count given as a float, a bool or a string is a TypeError (``int()`` took
    max_steps=2.9 as 2, and a wrong type of reinject_every was a ValueError), one below 0 a
    ValueError: as tetloc.view's counts."""
    for bad in [2.9, True, "3", -1]:
        kwargs: Dict[str, Any] = {arg: bad}
        error, message = (ValueError, "expected at least 0, got -1") if bad == -1 else (TypeError, "expected a whole")
        with pytest.raises(error, match=f"{arg}: {message}"):
            tetloc.trace(swirl_mesh, "v", seeds(), backend="cpu", **kwargs)


def test_trace_edge_cases(swirl_mesh):
    """A step f64 cannot tell from none is refused (it gave no line and a misleading warning);
    no line at all still makes an (empty) pyvista PolyData, with the warning."""
    with pytest.raises(ValueError, match="too small"):
        tetloc.trace(swirl_mesh, "v", seeds(), step=1e-20, backend="cpu")
    with pytest.warns(RuntimeWarning, match="4 of 4 lines"):
        lines = tetloc.trace(swirl_mesh, "v", np.full((4, 3), 5.0), backend="cpu", as_pyvista=True)
    assert lines.n_points == 0


def test_cell_type_codes_are_checked():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float64)
    for bad in (266, -246, 2**32 + 10):
        with pytest.raises(ValueError, match="celltypes.*0 to 255"):
            tetloc.Mesh(pts, np.array([4, 0, 1, 2, 3]), celltypes=np.array([bad]))
    with pytest.raises(ValueError, match="0 to 255"):
        tetloc.Mesh(pts, {266: np.array([[0, 1, 2, 3]])})
    with pytest.raises(ValueError, match="0 to 255"):
        tetloc.Mesh(pts, {"tetra": np.array([[0, 1, 2, 3]])})
