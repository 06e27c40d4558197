#!/usr/bin/env python3
"""VTK's answers for tetloc's resample, probe and trace tests (crates/tetloc-cli/tests/ops.rs).

    vtk_ops.py resample MESH.vtu NX,NY,NZ OURS.vti OUT_DIR
    vtk_ops.py probe SOURCE.vtu TARGET OURS.vtu|.vtp OUT_DIR
    vtk_ops.py trace MESH.vtu VECTOR SEEDS.bin STEP MAX_STEPS DIRECTION OURS.vtp OUT_DIR [rk45 MIN MAX MAX_ERROR]

resample: vtkResampleToImage over the mesh's bounds; probe: vtkResampleWithDataSet of SOURCE
onto TARGET (a .vtu mesh, or raw float32 x,y,z points in a .bin); trace: vtkStreamTracer with
RK4 (or RK45, vtkRungeKutta45, with the step bounds and maximum error given), steps in length
units and seeds from SEEDS.bin (raw float32 x,y,z).

Writes to OUT_DIR VTK's arrays as vtk.NAME.bin (float64, point data, components
interleaved) and the file tetloc wrote, read by VTK's own XML reader, as tetloc.NAME.bin;
for images also vtk.geometry.json / tetloc.geometry.json (origin, spacing, dimensions); for
traces the lines as X.points.bin (float64 N x 3), X.offsets.bin (int64, one more than lines)
and the cell arrays X.ReasonForTermination.bin, X.SeedIds.bin (float64), X = vtk or tetloc.

Exits with status 3 when the `vtk` module is missing, so the test can tell that apart.
"""

import json
import os
import sys

from vtk_common import np, point_cloud, read_points, vtk, vtk_to_numpy  # exits 3 without vtk


def read(path):
    readers = {
        ".vtu": vtk.vtkXMLUnstructuredGridReader,
        ".vtp": vtk.vtkXMLPolyDataReader,
        ".vti": vtk.vtkXMLImageDataReader,
    }
    r = readers[os.path.splitext(path)[1]]()
    r.SetFileName(path)
    r.Update()
    out = r.GetOutput()
    if out.GetNumberOfPoints() == 0:
        sys.exit(f"vtk_ops.py: {path}: VTK read no points")
    return out


def dump(data, prefix, out_dir):
    """Every point array as PREFIX.NAME.bin (float64)."""
    pd = data.GetPointData()
    for i in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(i)
        vtk_to_numpy(a).astype(np.float64).tofile(os.path.join(out_dir, f"{prefix}.{a.GetName()}.bin"))


def geometry(img, prefix, out_dir):
    g = {"origin": img.GetOrigin(), "spacing": img.GetSpacing(), "dims": img.GetDimensions()}
    with open(os.path.join(out_dir, f"{prefix}.geometry.json"), "w") as f:
        json.dump(g, f)


def resample(mesh_path, dims, ours, out_dir):
    f = vtk.vtkResampleToImage()
    f.SetInputDataObject(read(mesh_path))
    f.SetUseInputBounds(True)
    f.SetSamplingDimensions(*[int(d) for d in dims.split(",")])
    f.Update()
    img = f.GetOutput()
    dump(img, "vtk", out_dir)
    geometry(img, "vtk", out_dir)
    mine = read(ours)
    dump(mine, "tetloc", out_dir)
    geometry(mine, "tetloc", out_dir)


def points_of(path):
    if path.endswith(".bin"):
        return point_cloud(read_points(path))
    return read(path)


def probe(source, target, ours, out_dir):
    f = vtk.vtkResampleWithDataSet()
    f.SetInputDataObject(points_of(target))
    f.SetSourceData(read(source))
    f.SetPassPointArrays(True)
    f.Update()
    dump(f.GetOutput(), "vtk", out_dir)
    mine = read(ours)
    dump(mine, "tetloc", out_dir)
    vtk_to_numpy(mine.GetPoints().GetData()).astype(np.float64).tofile(os.path.join(out_dir, "tetloc.points.bin"))


def lines(poly, prefix, out_dir):
    vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64).tofile(os.path.join(out_dir, f"{prefix}.points.bin"))
    ca = poly.GetLines()
    offsets = vtk_to_numpy(ca.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(ca.GetConnectivityArray()).astype(np.int64)
    # Points in line order (VTK's lines use their points in order, but say so explicitly).
    pts = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)[conn]
    pts.tofile(os.path.join(out_dir, f"{prefix}.points.bin"))
    offsets.tofile(os.path.join(out_dir, f"{prefix}.offsets.bin"))
    pd = poly.GetPointData()
    for i in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(i)
        vtk_to_numpy(a).astype(np.float64)[conn].tofile(os.path.join(out_dir, f"{prefix}.{a.GetName()}.bin"))
    cd = poly.GetCellData()
    for i in range(cd.GetNumberOfArrays()):
        a = cd.GetArray(i)
        vtk_to_numpy(a).astype(np.float64).tofile(os.path.join(out_dir, f"{prefix}.{a.GetName()}.bin"))


def trace(mesh_path, vector, seeds, step, max_steps, direction, ours, out_dir, *rk45):
    mesh = read(mesh_path)
    mesh.GetPointData().SetActiveVectors(vector)
    t = vtk.vtkStreamTracer()
    t.SetInputData(mesh)
    t.SetSourceData(points_of(seeds))
    t.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, vector)
    if rk45:
        t.SetIntegratorTypeToRungeKutta45()
        t.SetMinimumIntegrationStep(float(rk45[1]))
        t.SetMaximumIntegrationStep(float(rk45[2]))
        t.SetMaximumError(float(rk45[3]))
    else:
        t.SetIntegratorTypeToRungeKutta4()
    t.SetIntegrationStepUnit(vtk.vtkStreamTracer.LENGTH_UNIT)
    t.SetInitialIntegrationStep(float(step))
    t.SetMaximumNumberOfSteps(int(max_steps))
    t.SetMaximumPropagation(1e30)
    t.SetTerminalSpeed(1e-12)
    t.SetComputeVorticity(False)
    t.SetIntegrationDirection({"forward": 0, "backward": 1, "both": 2}[direction])
    t.Update()
    lines(t.GetOutput(), "vtk", out_dir)
    lines(read(ours), "tetloc", out_dir)


if __name__ == "__main__":
    ops = {"resample": (resample, [4]), "probe": (probe, [4]), "trace": (trace, [8, 12])}
    if len(sys.argv) < 2 or sys.argv[1] not in ops or len(sys.argv) - 2 not in ops[sys.argv[1]][1]:
        sys.exit(__doc__)
    ops[sys.argv[1]][0](*sys.argv[2:])
