"""``tetloc.torch``'s zero-copy path (CUDA <-> Vulkan shared memory, issue 33) on a CUDA GPU,
run by scripts/h200/zerocopy.sh (not collected by pytest: CI has no CUDA device).

    python python/tests/cuda_zerocopy.py [--mesh MESH] [--leak-calls 10000] [--json out.json]

Checks: the path is the zero-copy one; ids equal the CPU backend's and the host path's for the
same float32 points; ``sample``'s values and both gradients equal the host path's (the kernel
writes the weights on this path); no host copy (``tetloc.torch.host_copies()`` stays 0) through locate,
sample and backward; non-finite points answer -1; a side stream gives the same ids; 10,000
``sample`` calls leave device memory flat (torch's allocator and the device's free memory,
which counts Vulkan's allocations too); meshes the path does not take are refused clearly with
``zero_copy=True``. Each check prints ``PASS name`` or ``FAIL name: why``; the exit status is
the number of failures.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import torch
from _cuda_checks import check, results, tally

import tetloc
import tetloc.torch as tt


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--mesh", type=pathlib.Path, required=True, help="a mesh of linear tets")
    parser.add_argument("--data", type=pathlib.Path, help="the oracle data (../shared/data): its mixed mesh")
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--leak-calls", type=int, default=10000)
    parser.add_argument("--json", type=pathlib.Path)
    args = parser.parse_args()
    dev = torch.device("cuda", torch.cuda.current_device())
    print("CUDA driver loadable:", tetloc._tetloc.cuda_driver_available(), flush=True)
    mesh = tetloc.read(str(args.mesh))
    loc = tt.Locator(mesh, device=dev)
    print("path:", loc.path, "| why not zero-copy:", loc.zero_copy_error, flush=True)
    if loc._cuda is not None:
        print("semaphores:", loc._cuda.semaphores, flush=True)
    g = torch.Generator(device="cpu").manual_seed(7)
    lo = torch.tensor(mesh.bounds[0::2], dtype=torch.float64)
    hi = torch.tensor(mesh.bounds[1::2], dtype=torch.float64)
    span = hi - lo
    host_pts = (lo - 0.05 * span + torch.rand(args.points, 3, generator=g, dtype=torch.float64) * 1.1 * span)
    host_pts = host_pts.to(torch.float32)
    pts = host_pts.to(dev)

    @check("path is zero-copy")
    def _() -> None:
        assert loc.path == "zero-copy", f"host path: {loc.zero_copy_error}"

    @check("ids equal the CPU backend's and the host path's")
    def _() -> None:
        got = loc.locate(pts).cpu().numpy()
        cpu = tetloc.Locator(mesh, backend="cpu").locate(host_pts.numpy())
        host = tt.Locator(mesh, device=dev, zero_copy=False).locate(pts).cpu().numpy()
        bad_cpu, bad_host = int((got != cpu).sum()), int((got != host).sum())
        inside = int((got >= 0).sum())
        print(f"  {len(got)} points, {inside} inside; differ from cpu: {bad_cpu}, from host path: {bad_host}")
        assert bad_cpu == 0 and bad_host == 0

    @check("no host copy through locate, sample and backward")
    def _() -> None:
        before = tt.host_copies()
        values = torch.rand(mesh.n_points, device=dev, requires_grad=True)
        p = pts[:100_000].clone().requires_grad_(True)
        loc.locate(pts)
        out = loc.sample(p, values, fill=0.0)
        out.sum().backward()
        torch.cuda.synchronize(dev)  # the check's own wait, outside the path
        assert values.grad is not None and p.grad is not None
        assert tt.host_copies() == before, f"{tt.host_copies() - before} host copies"

    @check("sample's values and gradients equal the host path's (the kernel's weights)")
    def _() -> None:
        host = tt.Locator(mesh, device=dev, zero_copy=False)
        values = torch.rand(mesh.n_points, 2, device=dev, dtype=torch.float32)
        outs = []
        for which in (loc, host):
            v = values.clone().requires_grad_(True)
            p = pts[:200_000].clone().requires_grad_(True)
            out = which.sample(p, v, fill=0.0)
            (out * torch.tensor([1.0, -2.0], device=dev)).sum().backward()
            assert v.grad is not None and p.grad is not None
            outs.append((out.detach(), v.grad, p.grad))
        (a, ga, pa), (b, gb, pb) = outs
        scale = max(1.0, float(b.abs().max()))
        print(f"  values differ by {float((a - b).abs().max()):.2e}, field gradients by "
              f"{float((ga - gb).abs().max()):.2e}, point gradients by {float((pa - pb).abs().max()):.2e}")
        assert float((a - b).abs().max()) <= 1e-5 * scale
        assert float((ga - gb).abs().max()) <= 1e-4 * max(1.0, float(gb.abs().max()))
        assert float((pa - pb).abs().max()) <= 1e-4 * max(1.0, float(pb.abs().max()))

    @check("non-finite points answer -1")
    def _() -> None:
        p = pts[:1000].clone()
        p[::7, 1] = float("nan")
        p[3::7, 0] = float("inf")
        ids = loc.locate(p).cpu()
        bad = ~torch.isfinite(p.cpu()).all(1)
        assert (ids[bad] == -1).all()
        assert torch.equal(ids[~bad], loc.locate(pts[:1000]).cpu()[~bad])

    @check("a side stream gives the same ids")
    def _() -> None:
        want = loc.locate(pts)
        s = torch.cuda.Stream(dev)
        s.wait_stream(torch.cuda.current_stream(dev))
        with torch.cuda.stream(s):
            got = loc.locate(pts)
        torch.cuda.current_stream(dev).wait_stream(s)
        assert torch.equal(got, want)

    @check(f"{args.leak_calls} sample calls leave device memory flat")
    def _() -> None:
        values = torch.rand(mesh.n_points, device=dev)
        p = pts[:10_000]

        def settle() -> tuple:
            torch.cuda.synchronize(dev)
            return torch.cuda.memory_allocated(dev), torch.cuda.mem_get_info(dev)[0]

        for _ in range(20):
            loc.sample(p, values)
        a0, f0 = settle()
        for _ in range(args.leak_calls):
            loc.sample(p, values)
        a1, f1 = settle()
        print(f"  torch allocated {a0} -> {a1} bytes; device free {f0} -> {f1} bytes")
        assert a1 <= a0 and f0 - f1 < (16 << 20), "memory grew"

    @check("a mixed mesh with zero_copy=True is refused clearly")
    def _() -> None:
        mixed = args.data / "mixed" / "hybrid.zlib.vtu" if args.data else None
        assert mixed is not None and mixed.exists(), "no --data with mixed/hybrid.zlib.vtu"
        try:
            tt.Locator(tetloc.read(str(mixed)), device=dev, zero_copy=True)
        except tetloc.DeviceError as e:
            print(f"  refused: {e}")
            assert "linear tets" in str(e)
            return
        raise AssertionError("not refused")

    @check("no Vulkan validation error (0 without the layer)")
    def _() -> None:
        if loc._cuda is not None:
            errors = loc._cuda.validation_errors()
            assert errors == 0, f"{errors} validation errors"

    failed = tally()
    if args.json:
        args.json.write_text(json.dumps({"path": loc.path, "why": loc.zero_copy_error, "results": results}, indent=1))
    return failed


if __name__ == "__main__":
    sys.exit(main())
