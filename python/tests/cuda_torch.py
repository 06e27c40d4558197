"""``tetloc.torch`` with CUDA tensors: the checks of python/tests/test_torch.py on a GPU, run by
scripts/h200/torch.sh (not collected by pytest: CI has no CUDA device).

    python python/tests/cuda_torch.py [--data DIR] [--leak-calls 10000]

Each check prints ``PASS name`` or ``FAIL name: why`` (and goes on); the exit status is the
number of failures. Host transfers are reported per call from ``tetloc.torch.host_copies()``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
from typing import List

import numpy as np
import torch
from _cuda_checks import check, results, tally

import tetloc
import tetloc.torch as tt


def kuhn_mesh(n: int) -> tetloc.Mesh:
    ax = np.linspace(0.0, 1.0, n + 1)
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    vid = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)  # noqa: E731
    k, j, i = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
    unit = np.eye(3, dtype=int)
    tets = []
    for a, b in ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)):
        e1, e12 = unit[a], unit[a] + unit[b]
        tets.append(np.stack([vid(i, j, k), vid(i + e1[0], j + e1[1], k + e1[2]),
                              vid(i + e12[0], j + e12[1], k + e12[2]), vid(i + 1, j + 1, k + 1)], axis=1))
    f = np.sin(3 * points[:, 0]) + points[:, 1] * points[:, 2]
    return tetloc.Mesh(points, np.stack(tets, axis=1).reshape(-1, 4), point_data={"f": f, "v": points})


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--data", type=pathlib.Path, help="the oracle data (../shared/data)")
    parser.add_argument("--leak-calls", type=int, default=10000)
    parser.add_argument("--json", type=pathlib.Path, help="write the results here")
    parser.add_argument("--device", default="cuda", help="cpu: a dry run of the script without a GPU")
    args = parser.parse_args()
    on_gpu = args.device != "cpu"
    if on_gpu:
        assert torch.cuda.is_available(), "no CUDA device"
        dev = torch.device("cuda", torch.cuda.current_device())
    else:
        dev = torch.device("cpu")
    other = torch.device("cpu") if on_gpu else torch.device("meta")
    gpu_name = torch.cuda.get_device_name(dev) if on_gpu else "cpu"
    print(f"torch {torch.__version__}, {gpu_name}; tetloc devices: {[d['name'] for d in tetloc.devices()]}", flush=True)

    def sync() -> None:
        if on_gpu:
            torch.cuda.synchronize(dev)

    meshes: List[tetloc.Mesh] = [kuhn_mesh(12)]
    if args.data:
        for rel in ("torus_s.vtu", "part_s.zlib.vtu", "mixed/hybrid.zlib.vtu", "mixed/hexwarp.zlib.vtu"):
            if (args.data / rel).exists():
                meshes.append(tetloc.read(args.data / rel))
    gen = torch.Generator().manual_seed(0)

    def random_points(mesh: tetloc.Mesh, n: int, dtype: torch.dtype) -> torch.Tensor:
        lo = torch.tensor(mesh.bounds[0::2], dtype=torch.float64)
        hi = torch.tensor(mesh.bounds[1::2], dtype=torch.float64)
        return (lo + (hi - lo) * torch.rand(n, 3, generator=gen, dtype=torch.float64)).to(dtype)

    for m_i, mesh in enumerate(meshes):
        label = f"mesh{m_i}({mesh.n_cells} cells)"
        cpu = tt.Locator(mesh, device="cpu", backend="cpu")
        gpu = tt.Locator(mesh, device=dev, backend="auto" if on_gpu else "cpu")
        name = "f" if "f" in mesh.point_data else None

        @check(f"{label}: ids and values as on the CPU ({gpu.backend})")
        def _() -> None:
            for dtype in (torch.float32, torch.float64):
                p = random_points(mesh, 100_000, dtype)
                ids_cpu = cpu.locate(p)
                ids_gpu = gpu.locate(p.to(dev))
                assert ids_gpu.device == dev and ids_gpu.dtype == torch.int32
                same = (ids_gpu.cpu() == ids_cpu)
                print(f"    {dtype}: {int((~same).sum())} of {len(same)} ids differ from the cpu backend's")
                # A GPU kernel may pick the other tet of a shared face (f32 decisions): rare.
                assert same.float().mean() > 0.9999, f"{dtype}: {(~same).sum()} ids differ"
                if name is not None:
                    v_cpu = cpu.sample(p, name)
                    v_gpu = gpu.sample(p.to(dev), name).cpu()
                    ok = same & ~torch.isnan(v_cpu)
                    assert torch.equal(torch.isnan(v_gpu[same]), torch.isnan(v_cpu[same]))
                    tol = 1e-5 if dtype == torch.float32 else 1e-9
                    err = (v_gpu[ok] - v_cpu[ok]).abs().max().item()
                    assert err <= tol * max(1.0, v_cpu[ok].abs().max().item()), f"{dtype}: values differ by {err}"

        @check(f"{label}: gradcheck float64 on CUDA (points and field)")
        def _() -> None:
            # Points well inside cells: a random mix of a cell's corners pulled to its centre.
            conn, off, pts = mesh.cell_connectivity, mesh.offsets, mesh.points64
            rng = np.random.default_rng(1)
            rows = []
            for c in rng.integers(0, mesh.n_cells, size=8):
                corners = pts[conn[off[c]:off[c + 1]]][: {8: 8, 6: 6, 5: 5}.get(int(off[c + 1] - off[c]), 4)]
                rows.append(0.5 * corners.mean(0) + 0.5 * rng.dirichlet(np.ones(len(corners))) @ corners)
            p = torch.tensor(np.array(rows), device=dev, requires_grad=True)
            f = torch.randn(mesh.n_points, 2, dtype=torch.float64, device=dev, requires_grad=True)
            assert torch.autograd.gradcheck(lambda a, b: gpu.sample(a, b), (p, f), eps=1e-6, atol=1e-6, fast_mode=True)

    mesh = meshes[0]
    gpu = tt.Locator(mesh, device=dev, backend="auto" if on_gpu else "cpu")

    @check("bad input: clear Python errors, no CUDA fault")
    def _() -> None:
        good = torch.rand(10, 3, device=dev)
        cases = [
            (lambda: gpu.locate(torch.rand(10, 3, device=other)), ValueError, f"on {other}, but this Locator is on"),
            (lambda: gpu.locate(torch.rand(3, 10, device=dev).t()), ValueError, "not contiguous"),
            (lambda: gpu.locate(torch.rand(10, 2, device=dev)), ValueError, "shape"),
            (lambda: gpu.locate(torch.ones(10, 3, dtype=torch.int32, device=dev)), TypeError, "dtype"),
            (lambda: gpu.sample(good, torch.ones(7, device=dev)), ValueError, "field: shape"),
            (lambda: gpu.sample(good, torch.ones(mesh.n_points, device=other)), ValueError, f"field: on {other}"),
        ]
        for call, kind, text in cases:
            try:
                call()
            except kind as e:
                assert text in str(e), f"{kind.__name__} without '{text}': {e}"
            else:
                raise AssertionError(f"no {kind.__name__} for '{text}'")
        sync()  # no fault was left behind

    p = torch.rand(1_000_000 if on_gpu else 20_000, 3, device=dev)
    copies: List[int] = []
    field = torch.rand(mesh.n_points, device=dev, requires_grad=True)

    @check("host copies per sample call (0 is the zero-copy target)")
    def _() -> None:
        before = tt.host_copies()
        gpu.sample(p, field).sum().backward()
        per_call = tt.host_copies() - before
        copies.append(per_call)
        print(f"    host copies per sample call (forward + backward): {per_call}")
        assert per_call == 0, f"{per_call} host transfers per call"

    @check(f"no leak: {args.leak_calls} sample calls leave device memory flat")
    def _() -> None:
        small = p[:10_000]
        for _ in range(100):  # warm the caching allocator
            gpu.sample(small, field)
        if not on_gpu:
            return
        sync()
        alloc0, free0 = torch.cuda.memory_allocated(dev), torch.cuda.mem_get_info(dev)[0]
        for _ in range(args.leak_calls):
            gpu.sample(small, field)
        sync()
        alloc1, free1 = torch.cuda.memory_allocated(dev), torch.cuda.mem_get_info(dev)[0]
        print(f"    torch allocated {alloc0} -> {alloc1} B; device free {free0} -> {free1} B")
        assert alloc1 <= alloc0, "torch's allocations grew"
        assert free0 - free1 < 64 << 20, f"device memory fell by {(free0 - free1) >> 20} MiB"

    if args.json:
        args.json.write_text(json.dumps({"checks": results, "host_copies_per_sample_call": copies}, indent=1))
    return tally()


if __name__ == "__main__":
    sys.exit(main())
