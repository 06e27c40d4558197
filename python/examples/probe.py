#!/usr/bin/env python3
"""Probe a field of a tetrahedral mesh on a plane and plot it with pyvista.

    python python/examples/probe.py MESH FIELD [--backend auto] [--out probe.png]

Reads MESH (.vtu, .vtk, .msh, .node/.ele), samples FIELD on a 500x500 grid across the
middle of the mesh's box (NaN outside the mesh), and draws the slice over the mesh's outline.
"""

import argparse

import numpy as np
import pyvista as pv

import tetloc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("field")
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--size", type=int, default=500)
    ap.add_argument("--out", help="write a PNG instead of opening a window")
    args = ap.parse_args()

    mesh = tetloc.read(args.mesh)
    loc = tetloc.Locator(mesh, backend=args.backend, progress=True)
    print(mesh, f"\nlocating on {loc.backend}")

    # A plane through the middle of the box, normal to z: (size, size, 3) points.
    x0, x1, y0, y1, z0, z1 = mesh.bounds
    x, y = np.meshgrid(np.linspace(x0, x1, args.size), np.linspace(y0, y1, args.size), indexing="ij")
    plane = np.stack([x, y, np.full_like(x, (z0 + z1) / 2)], axis=-1)
    ids, values = loc.locate_and_sample(plane, args.field)  # shapes (size, size) (and a k axis for vectors)
    print(f"{np.count_nonzero(ids >= 0)} of {ids.size} plane points inside the mesh")

    slice_ = pv.StructuredGrid(x, y, plane[..., 2])
    slice_.point_data[args.field] = values.reshape(ids.size, -1, order="F").squeeze()
    plotter = pv.Plotter(off_screen=args.out is not None)
    plotter.add_mesh(mesh.to_pyvista().outline(), color="black")
    plotter.add_mesh(slice_, scalars=args.field, nan_opacity=0.0)
    if args.out:
        plotter.screenshot(args.out)
        print(f"wrote {args.out}")
    else:
        plotter.show()


if __name__ == "__main__":
    main()
