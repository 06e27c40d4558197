"""What the scripts/vtk_*.py references of the Rust tests share. They run by path (through
tetloc_testdata::run_vtk_script), so they import this from beside them.

Importing it without the `vtk` or `numpy` module exits with status 3, which the tests tell
apart from a failure (they skip then, outside CI).
"""

import os
import sys

try:
    import numpy as np
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy
except ImportError as e:
    print(f"{os.path.basename(sys.argv[0])}: {e} (pip install vtk numpy)", file=sys.stderr)
    sys.exit(3)

__all__ = ["np", "numpy_to_vtk", "point_cloud", "read_points", "vtk", "vtk_to_numpy"]


def read_points(path):
    """The points of a raw file of little-endian float32 x,y,z triplets, (N, 3) float64."""
    return np.fromfile(path, dtype="<f4").reshape(-1, 3).astype(np.float64)


def point_cloud(pts):
    """A vtkPolyData of the points `pts` (N x 3) alone: what the probe and tracer filters take."""
    cloud = vtk.vtkPolyData()
    vp = vtk.vtkPoints()
    vp.SetData(numpy_to_vtk(pts, deep=1))
    cloud.SetPoints(vp)
    return cloud
