"""The Python API answers exactly as the ``tetloc`` CLI: ids, values, and ``info --json``."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from conftest import query_sets

import tetloc


def run(cli: str, *args: str) -> str:
    out = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout


@pytest.mark.parametrize("name", ["torus_s.vtu", "part_s.msh22.msh", "delaunay_s.vtk"])
def test_locate_and_sample_match_the_cli(cli, data_dir, oracle_sets, tmp_path, name):
    # Both keep the f64 field's values as float64.
    assert same_answers_as_the_cli(cli, data_dir / name, oracle_sets, tmp_path) == np.float64


@pytest.mark.parametrize("name", ["torus_s.vtu", "part_s.vtu", "delaunay_s.vtu"])
def test_locate_and_sample_match_the_cli_on_generated_meshes(cli, generated_data, tmp_path, name):
    """The fresh-clone counterpart (float32 fields: float32 values from both)."""
    sets = query_sets(generated_data)
    assert same_answers_as_the_cli(cli, generated_data / name, sets, tmp_path) == np.float32


def same_answers_as_the_cli(cli, path, sets, tmp_path) -> np.dtype:
    """Checks the CLI's and Python's ids and values of `f` at the points of `path`'s sets;
    returns the values' dtype."""
    label = path.name.split(".")[0]
    points = np.concatenate([s.points for s in sets if s.label.startswith(label + ".")])
    np.save(tmp_path / "p.npy", points.astype(np.float64))  # f64 in: both round to f32
    run(cli, "locate", path, "--points", tmp_path / "p.npy", "--out", tmp_path / "ids.npy",
        "--field", "f", "--values", tmp_path / "v.npy", "--backend", "cpu")
    mesh = tetloc.read(path)
    ids, values = tetloc.Locator(mesh, backend="cpu").locate_and_sample(points.astype(np.float64), "f")
    np.testing.assert_array_equal(ids, np.load(tmp_path / "ids.npy"))
    theirs = np.load(tmp_path / "v.npy")
    assert values.dtype == theirs.dtype
    np.testing.assert_array_equal(values, theirs)
    return values.dtype


@pytest.mark.parametrize("name", ["part_s.vtu", "real/post.vtk"])
def test_info_is_the_clis_info_json(cli, data_dir, name):
    path = str(data_dir / name)
    assert tetloc.read(path).info() == json.loads(run(cli, "info", path, "--json"))


@pytest.mark.parametrize("name", ["part_s.vtu", "delaunay_s.vtu"])
def test_info_is_the_clis_info_json_on_generated_meshes(cli, generated_data, name):
    """The fresh-clone counterpart."""
    path = str(generated_data / name)
    assert tetloc.read(path).info() == json.loads(run(cli, "info", path, "--json"))


@pytest.mark.parametrize("backend", ["cpu", "auto"])
@pytest.mark.parametrize("options", [{}, {"tolerance": "1%"}, {"precision": "f64", "tolerance": 0.01}])
def test_the_same_options_build_the_same_stack(cli, data_dir, tmp_path, backend, options):
    """Python and the CLI build their locators through one front door: the same backend and
    options give the same layers (TETLOC_EXPLAIN=1 makes the CLI say its stack)."""
    same_stack(cli, data_dir / "torus_s.vtu", tmp_path, backend, options)


@pytest.mark.parametrize("backend", ["cpu", "auto"])
@pytest.mark.parametrize("options", [{}, {"tolerance": "1%"}, {"precision": "f64", "tolerance": 0.01}])
def test_the_same_options_build_the_same_stack_on_a_generated_mesh(cli, generated_data, tmp_path, backend, options):
    """The fresh-clone counterpart."""
    same_stack(cli, generated_data / "torus_s.vtu", tmp_path, backend, options)


def same_stack(cli, mesh, tmp_path, backend, options) -> None:
    import os

    np.save(tmp_path / "p.npy", np.zeros((1, 3)))
    args = [cli, "locate", str(mesh), "--points", str(tmp_path / "p.npy"), "--out",
            str(tmp_path / "ids.npy"), "--backend", backend, "--quiet"]
    for k, v in options.items():
        args += [f"--{k}", str(v)]
    out = subprocess.run(args, capture_output=True, text=True, env={**os.environ, "TETLOC_EXPLAIN": "1"})
    assert out.returncode == 0, out.stderr
    said = [line for line in out.stderr.splitlines() if line.startswith("locator: ")]
    assert len(said) == 1, out.stderr
    loc = tetloc.Locator(tetloc.read(mesh), backend=backend, **options)
    assert said[0] == "locator: " + " > ".join(loc.stack)
    want = ["FiniteOnly", "CellLocator"] + ["F64Values"] * ("precision" in options) + ["WithTolerance"] * bool(options)
    assert loc.stack[1:] == want


def test_the_readmes_trace_example_runs_on_a_generated_mesh(cli, tmp_path):
    """python/README.md says how to make a mesh with a vector field (`gen ... --vector`) for
    its `trace` example; that mesh traces."""
    readme = (tetloc_root() / "python" / "README.md").read_text()
    assert "--vector" in readme and "tetloc.trace(" in readme
    path = tmp_path / "fusion.vtu"
    run(cli, "gen", "fusion", "--tets", "20k", "--vector", "-o", path)
    mesh = tetloc.read(path)
    assert mesh.point_data["v"] == (mesh.n_points, 3)
    seeds = mesh.points[mesh.tets[::2000]].mean(axis=1)
    lines = tetloc.trace(mesh, "v", seeds, max_steps=20, backend="cpu")
    assert len(lines["offsets"]) - 1 == len(seeds) and len(lines["points"]) > len(seeds)


def tetloc_root():
    import pathlib

    return pathlib.Path(__file__).resolve().parents[2]
