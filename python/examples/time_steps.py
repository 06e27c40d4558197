#!/usr/bin/env python3
"""Locate once, interpolate every time step: the history of a field at probe points.

    python python/examples/time_steps.py SERIES FIELD [--points 1000] [--backend auto] [--out history.npy]

Reads SERIES (an Exodus II file, a .pvd, a Gmsh file of several steps), scatters probe
points through the mesh's box, locates them once (``Locator.step_weights``: on the GPU for a
GPU backend) and interpolates FIELD at every step, read from the file a batch of steps at a
time: an array of (steps, points), NaN at probes outside the mesh.
"""

import argparse
import time

import numpy as np

import tetloc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("series")
    ap.add_argument("field")
    ap.add_argument("--points", type=int, default=1000)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--out", help="save the (steps, points) history as .npy")
    args = ap.parse_args()

    mesh = tetloc.read(args.series)
    if not mesh.times:
        raise SystemExit(f"{args.series} is a single snapshot: no time steps")
    lo, hi = np.reshape(mesh.bounds, (3, 2)).T
    probes = np.random.default_rng(0).uniform(lo, hi, size=(args.points, 3))
    t0 = time.perf_counter()
    weights = tetloc.Locator(mesh, backend=args.backend).step_weights(probes)
    history = weights.sample(args.field)
    seconds = time.perf_counter() - t0
    inside = ~np.isnan(history[0])
    print(f"{len(mesh.times)} steps ({mesh.times[0]} to {mesh.times[-1]}) of '{args.field}' at {args.points} probes "
          f"({inside.sum()} inside the mesh) on {weights.device} in {seconds:.2f} s")
    for k in (0, len(mesh.times) - 1):
        print(f"  step {k} (t = {mesh.times[k]}): mean {np.nanmean(history[k]):.6g}, max {np.nanmax(history[k]):.6g}")
    if args.out:
        np.save(args.out, history)


if __name__ == "__main__":
    main()
