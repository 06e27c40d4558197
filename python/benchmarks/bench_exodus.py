#!/usr/bin/env python3
"""The Exodus II reader's rate in MB/s on a large netCDF-4 file.

Writes an Exodus II file as SEACAS lays it out in netCDF-4 (HDF5): one TETRA4 block of a
generated fusion mesh (``tetloc gen fusion --tets N``), f64 coordinates, a nodal variable
``f`` at ``--steps`` times, with the ``netCDF4`` package (``pip install netCDF4``; not a
dependency of tetloc). Then times, each the best of ``--repeats`` runs (the file in the page
cache after the first):

  - ``tetloc.read(FILE)``: the mesh and the first step's fields, validation included;
  - ``Mesh.field("f", step=k)`` for every step: one step's slice of the variable;
  - ``tetloc.read`` of the same mesh as an appended-raw ``.vtu`` (the format's reference: the
    validation's share of the first row is the same in both).

Run from the repository root:  python python/benchmarks/bench_exodus.py --tets 62M [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import time
from typing import Any, Dict, List

import numpy as np

import tetloc

REPO = pathlib.Path(__file__).resolve().parents[2]


def count(s: str) -> int:
    scale = {"k": 1e3, "M": 1e6}.get(s[-1], 1.0)
    return int(float(s.rstrip("kM")) * scale)


def write_exodus(path: pathlib.Path, mesh: tetloc.Mesh, steps: int) -> None:
    """`mesh` (linear tets) as an Exodus II netCDF-4 file with the nodal variable f = x + 2y +
    3z + t at times 0, 1, ..."""
    import netCDF4

    pts = mesh.points64
    tets = np.asarray(mesh.tets, dtype=np.int32) + 1  # Exodus counts nodes from 1
    with netCDF4.Dataset(str(path), "w", format="NETCDF4") as nc:
        nc.title = "tetloc bench_exodus"
        nc.api_version, nc.version, nc.floating_point_word_size = np.float32(8.0), np.float32(8.0), np.int32(8)
        nc.createDimension("len_string", 33)
        nc.createDimension("len_name", 33)
        nc.createDimension("time_step", None)
        nc.createDimension("num_dim", 3)
        nc.createDimension("num_nodes", len(pts))
        nc.createDimension("num_elem", len(tets))
        nc.createDimension("num_el_blk", 1)
        nc.createDimension("num_el_in_blk1", len(tets))
        nc.createDimension("num_nod_per_el1", 4)
        nc.createDimension("num_nod_var", 1)
        for k, axis in enumerate("xyz"):
            nc.createVariable(f"coord{axis}", "f8", ("num_nodes",))[:] = pts[:, k]
        connect = nc.createVariable("connect1", "i4", ("num_el_in_blk1", "num_nod_per_el1"))
        connect.elem_type = "TETRA4"
        connect[:] = tets
        nc.createVariable("eb_status", "i4", ("num_el_blk",))[:] = [1]
        prop = nc.createVariable("eb_prop1", "i4", ("num_el_blk",))
        prop.setncattr("name", "ID")
        prop[:] = [1]
        names = nc.createVariable("name_nod_var", "S1", ("num_nod_var", "len_name"))
        names[0, :] = netCDF4.stringtoarr("f", 33)
        time_whole = nc.createVariable("time_whole", "f8", ("time_step",))
        f = nc.createVariable("vals_nod_var1", "f8", ("time_step", "num_nodes"))
        base = pts @ np.array([1.0, 2.0, 3.0])
        for t in range(steps):
            time_whole[t] = float(t)
            f[t, :] = base + t


def best(repeats: int, run: Any) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        run()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tets", default="62M", help="tets of the generated fusion mesh (default 62M)")
    ap.add_argument("--steps", type=int, default=3, help="time steps of the nodal variable (default 3)")
    ap.add_argument("--repeats", type=int, default=2, help="runs of each timing, best taken (default 2)")
    ap.add_argument("--dir", default="/tmp/tetloc-bench-exodus", help="where the files go")
    ap.add_argument("--cli", default=os.environ.get("TETLOC_CLI", str(REPO / "target" / "release" / "tetloc")))
    ap.add_argument("--json", help="also write the results here")
    args = ap.parse_args()
    out = pathlib.Path(args.dir)
    out.mkdir(parents=True, exist_ok=True)
    vtu, exo = out / f"fusion_{args.tets}.vtu", out / f"fusion_{args.tets}.e"
    if not vtu.exists():
        subprocess.run([args.cli, "gen", "fusion", "--tets", args.tets, "-o", str(vtu), "-q"], check=True)
    if not exo.exists():
        t = time.perf_counter()
        write_exodus(exo, tetloc.read(str(vtu)), args.steps)
        print(f"wrote {exo} in {time.perf_counter() - t:.1f} s", file=sys.stderr)
    mb = exo.stat().st_size / 1e6
    mesh = tetloc.read(str(exo))
    n_tets, n_points, n_steps = mesh.n_tets, mesh.n_points, len(mesh.times)
    del mesh
    read_s = best(args.repeats, lambda: tetloc.read(str(exo)))
    mesh = tetloc.read(str(exo))
    step_s = [best(args.repeats, lambda k=k: mesh.field("f", step=k)) for k in range(n_steps)]
    vtu_mb = vtu.stat().st_size / 1e6
    vtu_s = best(args.repeats, lambda: tetloc.read(str(vtu)))
    step_mb = n_points * 8 / 1e6
    rows: List[Dict[str, Any]] = [
        {"what": "tetloc.read (mesh and step 0, validated)", "seconds": read_s, "MB": mb, "MB/s": mb / read_s},
        {"what": "Mesh.field('f', step=k), mean over steps", "seconds": float(np.mean(step_s)), "MB": step_mb,
         "MB/s": step_mb / float(np.mean(step_s))},
        {"what": "tetloc.read of the same mesh as .vtu (appended raw)", "seconds": vtu_s, "MB": vtu_mb,
         "MB/s": vtu_mb / vtu_s},
    ]
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs"
    print(f"{exo.name}: {n_tets} tets, {n_points} points, {n_steps} steps, {mb:.0f} MB (netCDF-4); {machine}")
    print("| what | seconds | MB | MB/s |\n|---|---|---|---|")
    for r in rows:
        print(f"| {r['what']} | {r['seconds']:.3f} | {r['MB']:.0f} | {r['MB/s']:.0f} |")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"file": str(exo), "tets": n_tets, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
