#!/usr/bin/env python3
"""VTK's view of an OpenFOAM case, for tetloc's OpenFOAM tests (crates/tetloc-io/src/openfoam/tests.rs).

    vtk_openfoam.py CASE.foam OUT.json [decomposed]

Reads the case with vtkOpenFOAMReader (vtkPOpenFOAMReader with CaseType 0 for a decomposed
case), as ParaView does: SkipZeroTime on (ParaView's default), 64-bit floats, no cell-to-point
data, the internal mesh only. VTK 9.7 keeps polyhedra whole (VTK_POLYHEDRON), so no
decomposition option needs turning off (older VTKs had DecomposePolyhedra, on by default:
turned off here when present). A decomposed case read serially comes back as one block per
processor; their cells are listed in processor order.

Writes OUT.json: times; and per time step the cell arrays (name -> flat values,
components interleaved); and once: the cells (VTK type and the coordinates of its distinct
points, sorted), and the number of points.

Exits with status 3 when the `vtk` module is missing, so the test can tell that apart.
"""

import json
import sys

from vtk_common import vtk, vtk_to_numpy  # exits 3 without vtk


def internal_meshes(output):
    """The internalMesh unstructured grids of the reader's output (one per processor)."""
    out = []
    it = output.NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        name = it.GetCurrentMetaData().Get(vtk.vtkCompositeDataSet.NAME())
        if name == "internalMesh":
            out.append(it.GetCurrentDataObject())
        it.GoToNextItem()
    return out


def main():
    path, out_path = sys.argv[1], sys.argv[2]
    decomposed = len(sys.argv) > 3 and sys.argv[3] == "decomposed"
    if decomposed:
        reader = vtk.vtkPOpenFOAMReader()
        reader.SetCaseType(0)
    else:
        reader = vtk.vtkOpenFOAMReader()
    reader.SetFileName(path)
    if hasattr(reader, "SetDecomposePolyhedra"):
        reader.SetDecomposePolyhedra(0)
    reader.SetSkipZeroTime(1)
    reader.SetUse64BitFloats(1)
    reader.SetCreateCellToPoint(0)
    reader.UpdateInformation()
    reader.EnableAllCellArrays()
    times = [float(t) for t in (reader.GetTimeValues() or [])]
    result = {"times": times, "steps": []}
    for k, t in enumerate(times or [None]):
        if t is not None:
            reader.UpdateTimeStep(t)
        else:
            reader.Update()
        grids = internal_meshes(reader.GetOutput())
        if k == 0:
            cells = []
            for g in grids:
                pts = vtk_to_numpy(g.GetPoints().GetData()).astype(float)
                for c in range(g.GetNumberOfCells()):
                    ids = vtk.vtkIdList()
                    g.GetCellPoints(c, ids)
                    corners = sorted({tuple(pts[ids.GetId(i)]) for i in range(ids.GetNumberOfIds())})
                    cells.append([g.GetCellType(c), [list(p) for p in corners]])
            result["cells"] = cells
            result["n_points"] = sum(g.GetNumberOfPoints() for g in grids)
        fields = {}
        for g in grids:
            cd = g.GetCellData()
            for i in range(cd.GetNumberOfArrays()):
                a = cd.GetArray(i)
                fields.setdefault(a.GetName(), []).extend(vtk_to_numpy(a).astype(float).ravel().tolist())
        result["steps"].append(fields)
    with open(out_path, "w") as f:
        json.dump(result, f)


if __name__ == "__main__":
    main()
