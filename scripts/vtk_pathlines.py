#!/usr/bin/env python3
"""VTK's pathlines for tetloc's `trace --unsteady` test (crates/tetloc-cli/tests/pathlines.rs).

    vtk_pathlines.py series OUT_DIR [hex]
    vtk_pathlines.py compare OUT_DIR START END OURS.vtp [N]
    vtk_pathlines.py streaks OUT_DIR START END OURS.vtp

series: writes OUT_DIR/series.pvd over OUT_DIR/step_K.vtu (a unit cube of tets, or with `hex` of
hexahedra, whose trilinear interpolation of the velocity differs from its tets'; with a velocity
`v` that rotates about x = y = 0.5 at a speed growing in time, plus a vertical swirl) and the
seeds as OUT_DIR/seeds.bin (raw float32 x,y,z). compare: runs vtkParticlePathFilter (RK4, its
default step of half an interval) on the same steps, held in memory, from START to END (step
times: VTK 9.7 injects at its input's first time and stops at the time asked for), and
writes its points and tetloc's (read by VTK's XML reader) as X.points.bin (float64 N x 3),
X.ids.bin (the particle: its seed index + 1000 x its injection time in 1e-4 units + 1e8 x its
ParticleId, from each program's own InjectedPointId, InjectionStepId and ParticleId) and
X.times.bin (the simulation time), float64, X = vtk or tetloc. N: VTK's
ForceReinjectionEveryNSteps (default 0); VTK's particles injected at END (one point each,
which make no line in tetloc) are left out; both also check that tetloc writes VTK's particle
arrays in VTK's types (ErrorCode and ParticleSourceId 0 in both). streaks: the same with vtkStreaklineFilter and
tetloc's `--streaklines` (times the particle age). compare, when OURS.vtp has `Vorticity`
(`--vorticity`), also runs VTK's ComputeVorticity and writes X.turning.bin (float64 N x 3: the
vorticity's x component, AngularVelocity, Rotation): VTK 9.7 stores its Vorticity array with one
component, the x, so that is what both give.

Exits with status 3 when the `vtk` module is missing, so the test can tell that apart.
"""

import os
import sys

from vtk_common import np, numpy_to_vtk, point_cloud, vtk, vtk_to_numpy  # exits 3 without vtk
from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase

TIMES = [0.0, 0.4, 0.8, 1.2, 1.6, 2.0]
SDDP = vtk.vtkStreamingDemandDrivenPipeline


def cube(n=10, kind="tet"):
    if kind == "hex":
        grid = vtk.vtkUnstructuredGrid()
        ijk = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)[:, ::-1]
        points = vtk.vtkPoints()
        points.SetData(numpy_to_vtk(ijk.astype(np.float64) / n, deep=True))
        grid.SetPoints(points)
        at = lambda i, j, k: (k * (n + 1) + j) * (n + 1) + i  # noqa: E731
        for k in range(n):
            for j in range(n):
                for i in range(n):
                    corners = [at(i, j, k), at(i + 1, j, k), at(i + 1, j + 1, k), at(i, j + 1, k),
                               at(i, j, k + 1), at(i + 1, j, k + 1), at(i + 1, j + 1, k + 1), at(i, j + 1, k + 1)]
                    grid.InsertNextCell(vtk.VTK_HEXAHEDRON, 8, corners)
        return grid
    img = vtk.vtkImageData()
    img.SetDimensions(n + 1, n + 1, n + 1)
    img.SetSpacing(1.0 / n, 1.0 / n, 1.0 / n)
    tets = vtk.vtkDataSetTriangleFilter()
    tets.SetInputData(img)
    tets.Update()
    grid = vtk.vtkUnstructuredGrid()
    grid.DeepCopy(tets.GetOutput())
    return grid


def velocity(p, t):
    x, y, z = p[:, 0] - 0.5, p[:, 1] - 0.5, p[:, 2]
    w = 1.0 + t
    return np.stack([-w * y, w * x, 0.15 * np.sin(2 * np.pi * p[:, 0]) * np.cos(2 * t) * (z * (1 - z)) * 4], 1)


def kind_of(out_dir):
    """The series' cells, as `series` wrote it down."""
    with open(os.path.join(out_dir, "kind")) as f:
        return f.read().strip()


def steps(kind):
    grids = []
    for t in TIMES:
        g = cube(kind=kind)
        p = vtk_to_numpy(g.GetPoints().GetData()).astype(np.float64)
        v = numpy_to_vtk(velocity(p, t).astype(np.float32), deep=True)
        v.SetName("v")
        g.GetPointData().AddArray(v)
        g.GetPointData().SetActiveVectors("v")
        grids.append(g)
    return grids


def seeds():
    rng = np.random.default_rng(3)
    r = rng.uniform(0.05, 0.35, 40)
    a = rng.uniform(0, 2 * np.pi, 40)
    z = rng.uniform(0.3, 0.7, 40)
    return np.stack([0.5 + r * np.cos(a), 0.5 + r * np.sin(a), z], 1).astype(np.float32)


def series(out_dir, kind="tet"):
    assert kind in ("tet", "hex"), kind
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "kind"), "w") as f:
        f.write(kind)
    lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "<Collection>"]
    for k, (t, g) in enumerate(zip(TIMES, steps(kind))):
        w = vtk.vtkXMLUnstructuredGridWriter()
        w.SetFileName(os.path.join(out_dir, f"step_{k}.vtu"))
        w.SetInputData(g)
        w.Write()
        lines.append(f'<DataSet timestep="{t!r}" part="0" file="step_{k}.vtu"/>')
    lines += ["</Collection>", "</VTKFile>"]
    with open(os.path.join(out_dir, "series.pvd"), "w") as f:
        f.write("\n".join(lines) + "\n")
    seeds().tofile(os.path.join(out_dir, "seeds.bin"))


class Series(VTKPythonAlgorithmBase):
    """The steps in memory, as a temporal source."""

    def __init__(self, start, kind):
        # A composite output: vtkParticlePathFilter (VTK 9.7) keeps a plain dataset input by
        # reference, so the step before would alias the source's reused output object and both
        # ends of an interval would hold the newer step. A fresh block a step avoids that.
        VTKPythonAlgorithmBase.__init__(self, nInputPorts=0, nOutputPorts=1, outputType="vtkMultiBlockDataSet")
        self.grids = steps(kind)
        # vtkParticlePathFilter injects at the first time its input has: the steps from START.
        self.times = [t for t in TIMES if t >= start]

    def RequestInformation(self, request, in_info, out_info):
        info = out_info.GetInformationObject(0)
        info.Set(SDDP.TIME_STEPS(), self.times, len(self.times))
        info.Set(SDDP.TIME_RANGE(), [self.times[0], self.times[-1]], 2)
        return 1

    def RequestData(self, request, in_info, out_info):
        info = out_info.GetInformationObject(0)
        t = info.Get(SDDP.UPDATE_TIME_STEP()) if info.Has(SDDP.UPDATE_TIME_STEP()) else TIMES[0]
        k = int(np.argmin([abs(t - s) for s in TIMES]))
        grid = vtk.vtkUnstructuredGrid()
        grid.ShallowCopy(self.grids[k])
        out = vtk.vtkMultiBlockDataSet.GetData(out_info)
        out.SetNumberOfBlocks(1)
        out.SetBlock(0, grid)
        out.GetInformation().Set(vtk.vtkDataObject.DATA_TIME_STEP(), TIMES[k])
        return 1


def write_arrays(pts, prefix, out_dir, ids, times):
    pts.tofile(os.path.join(out_dir, f"{prefix}.points.bin"))
    ids.astype(np.float64).tofile(os.path.join(out_dir, f"{prefix}.ids.bin"))
    times.astype(np.float64).tofile(os.path.join(out_dir, f"{prefix}.times.bin"))


def particle_key(seed, injected, particle=0):
    return seed + 1000.0 * np.round(injected * 1e4) + 1e8 * particle


def turning(pd, prefix, out_dir, keep=slice(None)):
    """The vorticity's x component, AngularVelocity and Rotation of `pd` into X.turning.bin."""
    vort = vtk_to_numpy(pd.GetArray("Vorticity")).astype(np.float64)
    vort_x = vort if vort.ndim == 1 else vort[:, 0]
    cols = [vort_x] + [vtk_to_numpy(pd.GetArray(n)).astype(np.float64) for n in ("AngularVelocity", "Rotation")]
    np.stack(cols, 1)[keep].tofile(os.path.join(out_dir, f"{prefix}.turning.bin"))


def run_filter(f, src, end):
    """VTK's particle filter `f` on the steps of `src` and the seeds, RK4, up to END."""
    f.SetInputConnection(0, src.GetOutputPort())
    f.SetInputData(1, point_cloud(seeds().astype(np.float64)))
    f.SetIntegratorType(1)  # RUNGE_KUTTA4
    f.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "v")
    f.UpdateTimeStep(float(end))  # VTK 9.7: integrates from the first input time to this one
    out = f.GetOutput()
    pd = out.GetPointData()
    seed = vtk_to_numpy(pd.GetArray("InjectedPointId")).astype(np.float64)
    # InjectionStepId indexes the input's times (those from START); ParticleAge is float32.
    injected = np.asarray(src.times)[vtk_to_numpy(pd.GetArray("InjectionStepId"))]
    age = vtk_to_numpy(pd.GetArray("ParticleAge")).astype(np.float64)
    particle = vtk_to_numpy(pd.GetArray("ParticleId")).astype(np.float64)
    return vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64), seed, injected, age, particle


def read_ours(ours):
    """tetloc's polylines: points, each point's line's seed, its point data, line offsets."""
    r = vtk.vtkXMLPolyDataReader()
    r.SetFileName(ours)
    r.Update()
    mine = r.GetOutput()
    cells = mine.GetLines()
    conn = vtk_to_numpy(cells.GetConnectivityArray())
    offs = vtk_to_numpy(cells.GetOffsetsArray())
    line_seed = vtk_to_numpy(mine.GetCellData().GetArray("SeedIds"))
    seed = np.empty(mine.GetNumberOfPoints())
    for i in range(len(offs) - 1):
        seed[conn[offs[i]:offs[i + 1]]] = line_seed[i]
    pts = vtk_to_numpy(mine.GetPoints().GetData()).astype(np.float64)
    return pts, seed, mine.GetPointData(), conn, offs


#: vtkParticlePathFilter's particle arrays (VTK 9.7); the last two are 0 at every point it writes.
PARTICLE_ARRAYS = ("ParticleId", "InjectedPointId", "InjectionStepId", "ParticleAge", "ErrorCode", "ParticleSourceId")


def same_particle_arrays(theirs, ours, streaks=False):
    """tetloc writes each of VTK's particle arrays in its numpy type (streaklines: the age is
    their time array, float64), and the constant ones equal."""
    for name in PARTICLE_ARRAYS:
        assert ours.HasArray(name), f"tetloc writes no {name}"
        a, b = vtk_to_numpy(theirs.GetArray(name)), vtk_to_numpy(ours.GetArray(name))
        assert a.dtype == b.dtype or (streaks and name == "ParticleAge"), f"{name}: VTK's {a.dtype}, tetloc's {b.dtype}"
    for name in PARTICLE_ARRAYS[-2:]:
        assert not vtk_to_numpy(theirs.GetArray(name)).any() and not vtk_to_numpy(ours.GetArray(name)).any(), name


def compare(out_dir, start, end, ours, every="0"):
    src = Series(float(start), kind_of(out_dir))  # held: the pipeline keeps no Python reference to it
    f = vtk.vtkParticlePathFilter()
    f.SetForceReinjectionEveryNSteps(int(every))
    pts, line_seed, pd, conn, offs = read_ours(ours)
    vorticity = pd.HasArray("Vorticity")
    f.SetComputeVorticity(vorticity)
    vtk_pts, seed, injected, age, particle = run_filter(f, src, end)
    same_particle_arrays(f.GetOutput().GetPointData(), pd)
    keep = injected < float(end)
    write_arrays(vtk_pts[keep], "vtk", out_dir, particle_key(seed, injected, particle)[keep], (age + injected)[keep])
    if vorticity:
        turning(f.GetOutput().GetPointData(), "vtk", out_dir, keep)
        turning(pd, "tetloc", out_dir)
    times = vtk_to_numpy(pd.GetArray("IntegrationTime"))
    # Each point's particle by tetloc's own arrays, named as VTK's: the key is VTK's.
    seed, particle = (vtk_to_numpy(pd.GetArray(n)).astype(np.float64) for n in ("InjectedPointId", "ParticleId"))
    injected = np.asarray(src.times)[vtk_to_numpy(pd.GetArray("InjectionStepId"))]
    age = vtk_to_numpy(pd.GetArray("ParticleAge")).astype(np.float64)
    first = np.empty(len(times))
    for i in range(len(offs) - 1):
        first[conn[offs[i]:offs[i + 1]]] = times[conn[offs[i]]]
    # The line's seed and first time (its injection) say the same as the arrays.
    assert np.array_equal(seed, line_seed) and np.array_equal(injected, first), "InjectedPointId, InjectionStepId"
    assert np.abs(age + injected - times).max() < 1e-6, "ParticleAge"
    write_arrays(pts, "tetloc", out_dir, particle_key(seed, injected, particle), times)


def streaks(out_dir, start, end, ours):
    src = Series(float(start), kind_of(out_dir))
    f = vtk.vtkStreaklineFilter()
    pts, seed, injected, age, particle = run_filter(f, src, end)
    write_arrays(pts, "vtk", out_dir, particle_key(seed, injected, particle), age)
    pts, line_seed, pd, _, _ = read_ours(ours)
    same_particle_arrays(f.GetOutput().GetPointData(), pd, streaks=True)
    seed, particle = (vtk_to_numpy(pd.GetArray(n)).astype(np.float64) for n in ("InjectedPointId", "ParticleId"))
    assert np.array_equal(seed, line_seed), "InjectedPointId"
    injected = np.asarray(src.times)[vtk_to_numpy(pd.GetArray("InjectionStepId"))]
    write_arrays(pts, "tetloc", out_dir, particle_key(seed, injected, particle), vtk_to_numpy(pd.GetArray("ParticleAge")))


if __name__ == "__main__":
    ops = {"series": (series, (1, 2)), "compare": (compare, (4, 5)), "streaks": (streaks, (4,))}
    if len(sys.argv) < 2 or sys.argv[1] not in ops or len(sys.argv) - 2 not in ops[sys.argv[1]][1]:
        sys.exit(__doc__)
    ops[sys.argv[1]][0](*sys.argv[2:])
