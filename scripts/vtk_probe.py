#!/usr/bin/env python3
"""VTK's answers for tetloc's boundary-tolerance test (crates/tetloc-cli/tests/cli.rs).

    vtk_probe.py MESH.vtu POINTS.bin TOLERANCE POINTSET OUT_DIR FIELD...

Probes MESH at POINTS (raw little-endian float32 x,y,z triplets) with vtkProbeFilter, its
tolerance set to TOLERANCE (absolute, mesh units), and writes to OUT_DIR:
  vtk.vtkValidPointMask.bin (uint8) and vtk.FIELD.bin (float64) for each FIELD;
then reads POINTSET (the .vtp or .vtu point set tetloc wrote) with VTK's own XML reader and
writes its point arrays as tetloc.NAME.bin (float64), and tetloc.points.bin (float64, N x 3).

Exits with status 3 when the `vtk` module is missing, so the test can tell that apart.
"""

import os
import sys

from vtk_common import np, point_cloud, read_points, vtk, vtk_to_numpy  # exits 3 without vtk


def main(mesh_path, points_path, tolerance, pointset_path, out_dir, *fields):
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(mesh_path)
    reader.Update()
    mesh = reader.GetOutput()
    if mesh.GetNumberOfCells() == 0:
        sys.exit(f"vtk_probe.py: {mesh_path}: VTK read no cells")

    pts = read_points(points_path)
    probe = vtk.vtkProbeFilter()
    probe.SetInputData(point_cloud(pts))
    probe.SetSourceData(mesh)
    probe.SetComputeTolerance(False)
    probe.SetTolerance(float(tolerance))
    probe.Update()
    pd = probe.GetOutput().GetPointData()
    arrays = {"vtkValidPointMask": np.uint8}
    arrays.update({f: np.float64 for f in fields})
    for name, dtype in arrays.items():
        a = pd.GetArray(name)
        if a is None:
            sys.exit(f"vtk_probe.py: the probe gave no array '{name}'")
        vtk_to_numpy(a).astype(dtype).tofile(os.path.join(out_dir, f"vtk.{name}.bin"))

    if pointset_path.endswith(".vtp"):
        ps_reader = vtk.vtkXMLPolyDataReader()
    else:
        ps_reader = vtk.vtkXMLUnstructuredGridReader()
    ps_reader.SetFileName(pointset_path)
    ps_reader.Update()
    ps = ps_reader.GetOutput()
    if ps.GetNumberOfPoints() != len(pts):
        sys.exit(f"vtk_probe.py: {pointset_path}: {ps.GetNumberOfPoints()} points, expected {len(pts)}")
    vtk_to_numpy(ps.GetPoints().GetData()).astype(np.float64).tofile(os.path.join(out_dir, "tetloc.points.bin"))
    ppd = ps.GetPointData()
    for i in range(ppd.GetNumberOfArrays()):
        a = ppd.GetArray(i)
        vtk_to_numpy(a).astype(np.float64).tofile(os.path.join(out_dir, f"tetloc.{a.GetName()}.bin"))


if __name__ == "__main__":
    if len(sys.argv) < 6:
        sys.exit(__doc__)
    main(*sys.argv[1:])
