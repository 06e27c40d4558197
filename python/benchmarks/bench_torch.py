"""``tetloc.torch.Locator.sample`` from CUDA tensors, against what a PyTorch user would do today
(issue 33): a nearest-vertex lookup (``torch.cdist`` in blocks) and ``grid_sample`` on a grid
resampled from the mesh with as much memory as the mesh. Run by scripts/h200/torch.sh.

    python bench_torch.py MESH.vtu [--points 16M] [--device cuda] [--json out.json]

Times are wall times in the caller's CUDA stream (events recorded on the current stream around
each call; everything included: host transfers, locating, interpolating). Errors are against
tetloc's own f64 interpolation at the same points (exact for linear tets), over points inside.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import time
from typing import Any, Dict

import numpy as np
import torch
import torch.nn.functional as F
from _torch_bench import count, timed

import tetloc
import tetloc.torch as tt


def errors(got: torch.Tensor, exact: torch.Tensor, field_range: float) -> Dict[str, float]:
    ok = torch.isfinite(exact)
    d = (got.to(torch.float64)[ok] - exact[ok]).abs()
    d = torch.nan_to_num(d, nan=field_range)  # a NaN where the mesh has a value counts as a range
    return {"mean_abs_error": d.mean().item(), "max_abs_error": d.max().item(),
            "mean_error_of_range": d.mean().item() / field_range}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("mesh", type=pathlib.Path)
    parser.add_argument("--points", default="16M")
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--cdist-points", default="256K", help="points the cdist baseline runs on (then scaled)")
    parser.add_argument("--cdist-block", type=int, default=1024)
    parser.add_argument("--json", type=pathlib.Path)
    args = parser.parse_args()
    dev = torch.device(args.device)
    if dev.type == "cuda" and dev.index is None:
        dev = torch.device("cuda", torch.cuda.current_device())
    out: Dict[str, Any] = {"mesh": str(args.mesh), "device": torch.cuda.get_device_name(dev) if dev.type == "cuda"
                           else "cpu", "torch": torch.__version__, "date": time.strftime("%Y-%m-%d %H:%M UTC",
                                                                                         time.gmtime())}

    t0 = time.perf_counter()
    mesh = tetloc.read(args.mesh)
    out["read_s"] = time.perf_counter() - t0
    out["n_tets"], out["n_points"] = mesh.n_tets, mesh.n_points
    t0 = time.perf_counter()
    loc = tt.Locator(mesh, device=dev)
    out["build_s"], out["backend"] = time.perf_counter() - t0, loc.backend
    print(f"{mesh}\nbackend {loc.backend}, built in {out['build_s']:.2f} s", flush=True)

    n = count(args.points)
    gen = torch.Generator(device=dev).manual_seed(0)
    b = mesh.bounds
    lo = torch.tensor(b[0::2], dtype=torch.float32, device=dev)
    hi = torch.tensor(b[1::2], dtype=torch.float32, device=dev)
    points = lo + (hi - lo) * torch.rand(n, 3, generator=gen, device=dev)
    vertices = torch.from_numpy(mesh.points64).to(dev)
    # A smooth field over the mesh's box, as vertex values.
    u = (vertices - lo.double()) / (hi - lo).double()
    field64 = torch.sin(6 * u[:, 0]) * torch.cos(4 * u[:, 1]) + u[:, 2]
    field = field64.float().requires_grad_(True)
    field_range = (field64.max() - field64.min()).item()

    exact = loc.sample(points.double(), field64)
    out["inside_fraction"] = torch.isfinite(exact).double().mean().item()

    copies = tt.host_copies()
    value = loc.sample(points, field)
    out["host_copies_per_sample"] = tt.host_copies() - copies
    out["tetloc"] = errors(value.detach(), exact, field_range)

    def forward() -> None:
        with torch.no_grad():
            loc.sample(points, field)

    out["forward"] = timed(dev, forward, args.repeats)

    def backward() -> None:
        loc.sample(points, field).backward(grad)

    grad = torch.ones(n, device=dev)
    backward()  # warm
    out["forward_backward"] = timed(dev, backward, args.repeats)
    fb = out["forward_backward"]["best_s"]
    out["backward_only_s"] = max(fb - out["forward"]["best_s"], 1e-9)
    for key in ("forward", "forward_backward"):
        out[key]["G_samples_per_s"] = n / out[key]["best_s"] / 1e9
    out["backward_G_samples_per_s"] = n / out["backward_only_s"] / 1e9
    print(f"tetloc.torch sample: forward {out['forward']['G_samples_per_s']:.3f} G/s, backward (alone) "
          f"{out['backward_G_samples_per_s']:.3f} G/s, {out['host_copies_per_sample']} host copies a call", flush=True)

    # Nearest vertex by torch.cdist in blocks, on a subset; its time scaled to all points.
    m = min(n, count(args.cdist_points))
    q = points[:m]
    vert32 = vertices.float()
    nearest = torch.empty(m, dtype=torch.int64, device=dev)

    def cdist() -> None:
        for s in range(0, m, args.cdist_block):
            nearest[s:s + args.cdist_block] = torch.cdist(q[s:s + args.cdist_block], vert32).argmin(1)

    t = timed(dev, cdist, 1)
    cd = {"points_run": m, "seconds_for_all_points": t["best_s"] * n / m,
          "G_samples_per_s": m / t["best_s"] / 1e9}
    cd.update(errors(field64[nearest].float(), exact[:m], field_range))
    out["cdist_nearest_vertex"] = cd
    print(f"cdist nearest vertex: {cd['G_samples_per_s'] * 1e3:.3f} M/s, mean error {cd['mean_error_of_range']:.2e} "
          "of the range", flush=True)

    # grid_sample on a grid of the mesh's memory: vertices (3 float32), tets (4 int32), field.
    mesh_bytes = 12 * mesh.n_points + 16 * mesh.n_tets + 4 * mesh.n_points
    voxels = mesh_bytes // 4
    ext = (hi - lo).double().cpu().numpy()
    h = (np.prod(ext) / voxels) ** (1 / 3)
    dims = [max(2, int(round(e / h))) for e in ext]  # x, y, z
    axes = [torch.linspace(float(lo[a]), float(hi[a]), dims[a], device=dev) for a in range(3)]
    gz, gy, gx = torch.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    grid_points = torch.stack([gx.reshape(-1), gy.reshape(-1), gz.reshape(-1)], 1)
    with torch.no_grad():
        grid_values = torch.cat([torch.nan_to_num(loc.sample(c.contiguous(), field.detach()), nan=0.0)
                                 for c in grid_points.split(1 << 24)])
    volume = grid_values.reshape(1, 1, dims[2], dims[1], dims[0])
    del grid_points, gx, gy, gz
    where = (2 * (points - lo) / (hi - lo) - 1).reshape(1, 1, 1, n, 3)  # (x, y, z) -> W, H, D
    sampled = torch.empty(n, device=dev)

    def grid() -> None:
        sampled[:] = F.grid_sample(volume, where, mode="bilinear", align_corners=True).reshape(n)

    t = timed(dev, grid, args.repeats)
    gs = {"dims": dims, "voxels": int(np.prod(dims)), "mesh_bytes": mesh_bytes,
          "G_samples_per_s": n / t["best_s"] / 1e9, "best_s": t["best_s"]}
    gs.update(errors(sampled, exact, field_range))
    out["grid_sample"] = gs
    print(f"grid_sample {dims}: {gs['G_samples_per_s']:.3f} G/s, mean error {gs['mean_error_of_range']:.2e} of the "
          "range", flush=True)
    out["targets"] = {"forward_10G": out["forward"]["G_samples_per_s"] >= 10,
                      "backward_5G": out["backward_G_samples_per_s"] >= 5}
    print(json.dumps(out, indent=1, default=lambda x: None if isinstance(x, float) and math.isnan(x) else x))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
