"""``tetloc.torch`` on CUDA tensors: the zero-copy path against the host path, in one run
(issue 33's targets: sample forward >= 10 G/s, backward >= 5 G/s at jets 12M, 16M points).
Run by scripts/h200/zerocopy.sh.

    python bench_zerocopy.py MESH.vtu [--points 16M] [--repeats 5] [--order random|morton]
                             [--no-host] [--json out.json]

Times are wall times between two CUDA events on the caller's current stream around each call,
everything included (for the host path: its transfers). The field is a CUDA tensor of vertex
values (requires_grad for the backward pass); points are float32, uniform in the mesh's box,
in random order or (``--order morton``, sorted before timing) along a Morton curve, as
coherent queries come (a grid, a mesh's own points, particles that moved a little).
"""

from __future__ import annotations

import argparse
import json
import pathlib
from typing import Any, Dict

import torch
from _torch_bench import count, timed

import tetloc
import tetloc.torch as tt


def morton(points: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor) -> torch.Tensor:
    """30-bit Morton codes of `points` in the box [lo, hi] (10 bits an axis)."""
    cells = ((points - lo) / (hi - lo) * 1023.0).clamp(0, 1023).to(torch.int64)
    code = torch.zeros(len(points), dtype=torch.int64, device=points.device)
    for bit in range(10):
        for axis in range(3):
            code |= ((cells[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("mesh", type=pathlib.Path)
    parser.add_argument("--points", default="16M")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--order", choices=("random", "morton"), default="random")
    parser.add_argument("--no-host", action="store_true", help="the zero-copy path only")
    parser.add_argument("--json", type=pathlib.Path)
    args = parser.parse_args()
    dev = torch.device("cuda", torch.cuda.current_device())
    mesh = tetloc.read(str(args.mesh))
    n = count(args.points)
    lo = torch.tensor(mesh.bounds[0::2], dtype=torch.float32, device=dev)
    hi = torch.tensor(mesh.bounds[1::2], dtype=torch.float32, device=dev)
    points = lo + (hi - lo) * torch.rand(n, 3, device=dev)
    if args.order == "morton":
        points = points[torch.argsort(morton(points, lo, hi))].contiguous()
    values = torch.rand(mesh.n_points, device=dev, requires_grad=True)
    out: Dict[str, Any] = {"mesh": str(args.mesh), "tets": mesh.n_cells, "points": n,
                           "order": args.order, "gpu": torch.cuda.get_device_name(dev), "torch": torch.__version__}
    for zero_copy in (True,) if args.no_host else (True, False):
        loc = tt.Locator(mesh, device=dev, zero_copy=zero_copy)
        key = loc.path
        copies = tt.host_copies()
        r: Dict[str, Any] = {"locate": timed(dev, lambda: loc.locate(points), args.repeats, warm=True)}
        r["forward"] = timed(dev, lambda: loc.sample(points, values), args.repeats, warm=True)

        def backward() -> None:
            loc.sample(points, values).sum().backward()

        r["forward_backward"] = timed(dev, backward, args.repeats, warm=True)
        r["backward_only_s"] = r["forward_backward"]["best_s"] - r["forward"]["best_s"]
        for k in ("locate", "forward"):
            r[k]["G_per_s"] = n / r[k]["best_s"] / 1e9
        # The difference of two timings: within their noise when the backward pass is cheap
        # beside the forward one (the host path's copies), then no rate (None), not a huge one.
        noise = abs(r["forward"]["median_s"] - r["forward"]["best_s"]) + 1e-4
        r["backward_G_per_s"] = n / r["backward_only_s"] / 1e9 if r["backward_only_s"] > noise else None
        r["host_copies"] = tt.host_copies() - copies
        out[key] = r
        back = "within the noise" if r["backward_G_per_s"] is None else f"{r['backward_G_per_s']:.2f} G/s"
        print(f"{key}: locate {r['locate']['G_per_s']:.2f} G/s, forward {r['forward']['G_per_s']:.2f} G/s, "
              f"backward {back}, {r['host_copies']} host copies", flush=True)
        del loc
        torch.cuda.empty_cache()
    if "zero-copy" in out and "host" in out:
        out["forward_speedup"] = out["zero-copy"]["forward"]["G_per_s"] / out["host"]["forward"]["G_per_s"]
    print(json.dumps(out, indent=1))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
