"""Fit a field's vertex values to scattered observations by gradient descent through
``tetloc.torch``'s differentiable ``sample``.

A generated mesh (``tetloc gen``'s shapes are not needed: a jittered box of tets made here)
carries a hidden field; observations are its values at random points. Starting from zero, the
vertex values are fitted so that sampling them at the observation points reproduces the
observations, plus a small smoothness term (sampled differences between nearby points), which
keeps vertices without observations in check.

    python examples/torch_fit.py                 # CUDA when there is one, else the CPU
    python examples/torch_fit.py --device cpu --steps 200
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

import tetloc
import tetloc.torch


def box_mesh(n: int, seed: int = 0) -> tetloc.Mesh:
    """n^3 cubes on [0, 1]^3, six tets each, interior vertices jittered."""
    rng = np.random.default_rng(seed)
    ax = np.linspace(0.0, 1.0, n + 1)
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    inner = ((points > 0) & (points < 1)).all(axis=1)
    points[inner] += rng.uniform(-0.2, 0.2, size=(inner.sum(), 3)) / n
    vid = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)  # noqa: E731
    k, j, i = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
    unit = np.eye(3, dtype=int)
    tets = []
    for a, b in ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)):  # Kuhn's six tets of a cube
        e1, e12 = unit[a], unit[a] + unit[b]
        tets.append(np.stack([vid(i, j, k), vid(i + e1[0], j + e1[1], k + e1[2]),
                              vid(i + e12[0], j + e12[1], k + e12[2]), vid(i + 1, j + 1, k + 1)], axis=1))
    return tetloc.Mesh(points, np.stack(tets, axis=1).reshape(-1, 4))


def hidden_field(p: torch.Tensor) -> torch.Tensor:
    return torch.sin(4 * p[:, 0]) * torch.cos(3 * p[:, 1]) + p[:, 2] ** 2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--cubes", type=int, default=12, help="cubes per side of the mesh")
    parser.add_argument("--observations", type=int, default=20000)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    device = torch.device(args.device)
    torch.manual_seed(0)

    mesh = box_mesh(args.cubes)
    loc = tetloc.torch.Locator(mesh, device=device)
    obs_points = torch.rand(args.observations, 3, dtype=torch.float64, device=device)
    obs = hidden_field(obs_points)
    truth = hidden_field(torch.from_numpy(mesh.points64).to(device))

    values = torch.zeros(mesh.n_points, dtype=torch.float64, device=device, requires_grad=True)
    optimizer = torch.optim.Adam([values], lr=0.05)
    # Pairs of points half a cube apart, both inside the box.
    step = torch.full((1, 3), 0.5 / args.cubes, dtype=torch.float64, device=device)
    pairs = torch.rand(args.observations, 3, dtype=torch.float64, device=device) * (1 - step)

    def misfit() -> float:
        with torch.no_grad():
            return float((loc.sample(obs_points, values) - obs).pow(2).mean().sqrt())

    print(f"rms misfit at the start: {misfit():.6f}")
    for i in range(args.steps):
        optimizer.zero_grad()
        data = (loc.sample(obs_points, values) - obs).pow(2).mean()
        smooth = (loc.sample(pairs + step, values) - loc.sample(pairs, values)).pow(2).mean()
        (data + 1e-3 * smooth).backward()
        optimizer.step()
        if (i + 1) % max(1, args.steps // 5) == 0:
            print(f"step {i + 1}: loss {float(data):.6f}")
    vertex_error = float((values.detach() - truth).abs().mean())
    print(f"mean vertex error against the hidden field: {vertex_error:.4f}")
    print(f"rms misfit at the end: {misfit():.6f}")


if __name__ == "__main__":
    main()
