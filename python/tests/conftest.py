"""Shared fixtures: the oracle data (``TETLOC_DATA`` or ``../shared/data`` beside the
repository), the ``tetloc`` CLI binary, a Vulkan device, and small test meshes.

As in the Rust tests, a missing oracle folder, CLI binary or Vulkan device skips the
tests that need it, except with ``CI`` set, where it fails them. Every skipped test, for
whatever reason, is also listed in the file ``TETLOC_SKIP_LOG`` names (``scripts/test.sh``
ends its run with the count), as ``nodeid<TAB>reason``.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import subprocess
from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np
import pytest

# Contexts read this when they open: every Vulkan call of the tests runs under the
# validation layer (when installed), and the session ends by checking its error count.
os.environ.setdefault("TETLOC_VK_VALIDATION", "1")

import tetloc  # noqa: E402
from tetloc import _tetloc  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]


def in_ci() -> bool:
    return os.environ.get("CI", "") not in ("", "0", "false")


def missing(what: str) -> None:
    """Skips the test (a user's clone may lack `what`); fails it in CI."""
    if in_ci():
        pytest.fail(f"{what} (CI must not skip)")
    pytest.skip(what)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Appends each skipped test to ``TETLOC_SKIP_LOG``: a skip must not pass for a pass."""
    log = os.environ.get("TETLOC_SKIP_LOG")
    if not (log and report.skipped):
        return
    # A skip's longrepr is (file, line, "Skipped: reason").
    reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
    reason = reason.removeprefix("Skipped: ").replace("\t", " ").replace("\n", " ")
    with open(log, "a", encoding="utf-8") as f:
        f.write(f"{report.nodeid}\t{reason}\n")


# The reason shared with the Rust tests' skips (tetloc_testdata::NO_DATA).
NO_DATA = "no ../shared oracle data [TETLOC_DATA]"


@pytest.fixture(scope="session")
def data_dir() -> pathlib.Path:
    d = pathlib.Path(os.environ.get("TETLOC_DATA") or REPO.parent / "shared" / "data")
    if not d.is_dir():
        missing(NO_DATA)
    return d


@pytest.fixture(scope="session")
def cli() -> str:
    """The tetloc binary: TETLOC_CLI, else target/release/tetloc, else target/debug/tetloc."""
    for candidate in (os.environ.get("TETLOC_CLI"), REPO / "target/release/tetloc", REPO / "target/debug/tetloc"):
        if candidate and pathlib.Path(candidate).is_file():
            return str(candidate)
    found = shutil.which("tetloc")
    if found:
        return found
    missing("no tetloc binary (cargo build -p tetloc-cli, or set TETLOC_CLI)")
    raise AssertionError  # unreachable


@pytest.fixture(scope="session")
def vulkan() -> Dict:
    """The device GPU backends use by default; in CI it must have ray tracing (lavapipe does)."""
    devs = tetloc.devices()
    if not devs:
        missing("no Vulkan device")
    if in_ci() and not all(d["ray_tracing"] for d in devs):
        pytest.fail("CI must run every backend: a Vulkan device lacks ray tracing")
    return devs[0]


@pytest.fixture(scope="session", autouse=True)
def no_validation_errors():
    yield
    assert _tetloc.validation_errors() == 0, "Vulkan validation errors (printed above)"


@dataclass
class QuerySet:
    label: str
    mesh_path: pathlib.Path
    points: np.ndarray  # (N, 3) float32
    cell: np.ndarray  # oracle ids, -1 outside
    value: Optional[np.ndarray]  # oracle values of field f (generated meshes), NaN outside
    flags: np.ndarray

    @property
    def ambiguous(self) -> np.ndarray:
        """Points within rounding of a face: another tet (or outside) is also right."""
        return (self.flags & 1) != 0


def query_sets(data: pathlib.Path) -> List[QuerySet]:
    """Every oracle query set in `data` and `data/real` (as tetloc_core::testdata does)."""
    out = []
    for folder in (data, data / "real"):
        for meta_path in sorted(folder.glob("*.*.json")):
            if meta_path.name.endswith(".mesh.json") or meta_path.name.count(".") != 2:
                continue
            meta = json.loads(meta_path.read_text())
            mesh = next(p for p in (folder / f"{meta['mesh']}.{e}" for e in ("vtu", "msh", "vtk")) if p.exists())

            def arr(key: str) -> Optional[np.ndarray]:
                a = meta["arrays"].get(key)
                p = folder / a["file"] if a else None
                return np.fromfile(p, dtype=np.dtype(a["dtype"])).reshape(a["shape"]) if p and p.exists() else None

            points, cell, flags = arr("points"), arr("cell"), arr("flags")
            assert points is not None and cell is not None and flags is not None, f"{meta_path}: arrays missing"
            out.append(QuerySet(f"{meta['mesh']}.{meta['set']}", mesh, points, cell, arr("value"), flags))
    return out


@pytest.fixture(scope="session")
def oracle_sets(data_dir) -> List[QuerySet]:
    sets = query_sets(data_dir)
    assert len(sets) >= 18, f"expected the oracle query sets in {data_dir}, found {len(sets)}"
    return sets


def kuhn_grid(n: int, spacing: float = 1.0):
    """n^3 cubes of side `spacing`, 6 Kuhn tets each (the Rust tests' KuhnGrid): vertices x
    fastest; each cube's tets [v0, v0+e_a, v0+e_a+e_b, v7] for the 6 axis orders."""
    ax = np.arange(n + 1) * spacing
    z, y, x = np.meshgrid(ax, ax, ax, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    vid = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)  # noqa: E731
    kk, jj, ii = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    i, j, k = ii.ravel(), jj.ravel(), kk.ravel()
    unit = np.eye(3, dtype=int)
    tets = []
    for a, b in ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)):
        e1, e12 = unit[a], unit[a] + unit[b]
        tets.append(
            np.stack(
                [vid(i, j, k), vid(i + e1[0], j + e1[1], k + e1[2]), vid(i + e12[0], j + e12[1], k + e12[2]),
                 vid(i + 1, j + 1, k + 1)],
                axis=1,
            )
        )
    cells = np.stack(tets, axis=1).reshape(-1, 4)
    return points, cells


@pytest.fixture(scope="session")
def grid_mesh() -> tetloc.Mesh:
    """A 6x6x6-cube Kuhn grid on [0, 6]^3 with f = x + 2y + 3z (linear: interpolation is
    exact), a vector field v = (x, y, z), and cell fields c = id and w = (id, -id)."""
    points, cells = kuhn_grid(6)
    ids = np.arange(len(cells), dtype=np.float64)
    return tetloc.Mesh(
        points,
        cells,
        point_data={"f": points @ [1.0, 2.0, 3.0], "v": points},
        cell_data={"c": ids, "w": np.stack([ids, -ids], axis=1)},
    )


def exact_values(mesh: tetloc.Mesh, ids: np.ndarray, points: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Barycentric interpolation in tet `ids[i]` with f64 barycentrics on the file's f64
    vertices (tetloc_testdata::exact_value); NaN where ids < 0."""
    out = np.full(len(ids), np.nan)
    inside = ids >= 0
    corners = mesh.points64
    v = corners[mesh.tets[ids[inside]]]  # (K, 4, 3)
    p = points[inside].astype(np.float64)

    def vol6(a, b, c, d):
        return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)

    tet = [v[:, 0], v[:, 1], v[:, 2], v[:, 3]]
    total = vol6(*tet)
    vals = values[mesh.tets[ids[inside]]].astype(np.float64)
    acc = np.zeros(len(p))
    for c in range(4):
        w = list(tet)
        w[c] = p
        acc += vol6(*w) / total * vals[:, c]
    out[inside] = acc
    return out


def same_mesh(a: tetloc.Mesh, b: tetloc.Mesh) -> None:
    """The same cells (types, nodes), points, tets and fields: what a round trip through
    pyvista, meshio or a file keeps."""
    assert (a.n_points, a.n_cells, a.n_tets) == (b.n_points, b.n_cells, b.n_tets)
    np.testing.assert_array_equal(a.points64, b.points64)
    np.testing.assert_array_equal(a.celltypes, b.celltypes)
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.cell_connectivity, b.cell_connectivity)
    np.testing.assert_array_equal(a.tets, b.tets)
    assert a.point_data == b.point_data and a.cell_data == b.cell_data
    for name in list(a.point_data) + list(a.cell_data):
        np.testing.assert_array_equal(a.field(name), b.field(name))


# --- The fresh-clone counterpart of ../shared/data (issue 30 item 1) ---------------------
# Meshes from the project's own generators (`tetloc gen`, with its fields `f` and `cellval`)
# under the shared meshes' names, and their query sets in the shared layout, so that
# `query_sets(generated_data)` feeds the oracle tests unchanged. The answers are computed
# here in float64 by brute force over every tet (as crates/tetloc-testdata's
# `generated_data` does with exact signs): the lowest tet whose barycentrics are all >= 0,
# flagged ambiguous (flags bit0) within 1e-6 of a face of any tet.

GENERATED = [("torus_s", "fusion", 6000), ("part_s", "agulhas", 4000), ("delaunay_s", "jets", 3000)]
GENERATED_SET_SIZE = 1000
AMBIGUOUS = 1e-6


def oracle_answers(mesh: tetloc.Mesh, points: np.ndarray):
    """(cell ids, -1 outside; values of `f`, NaN outside; flags) of float32 `points`."""
    corners = mesh.points64[mesh.tets]  # (T, 4, 3) at the file's precision
    v0 = corners[:, 0]
    inverse = np.linalg.inv(np.stack([corners[:, k] - v0 for k in (1, 2, 3)], axis=2))
    f = mesh.field("f").astype(np.float64)[mesh.tets]  # (T, 4)
    p64 = points.astype(np.float64)
    cell = np.full(len(p64), -1, np.int32)
    value = np.full(len(p64), np.nan)
    flags = np.zeros(len(p64), np.uint8)
    for start in range(0, len(p64), 32):
        p = p64[start : start + 32]
        b123 = np.einsum("tij,ptj->pti", inverse, p[:, None, :] - v0[None])
        bary = np.concatenate([1 - b123.sum(axis=2, keepdims=True), b123], axis=2)  # (P, T, 4)
        low = bary.min(axis=2)
        inside = low >= 0
        found = inside.any(axis=1)
        first = np.argmax(inside, axis=1)
        rows = np.arange(len(p))
        cell[start : start + len(p)] = np.where(found, first, -1)
        value[start : start + len(p)] = np.where(found, (bary[rows, first] * f[first]).sum(axis=1), np.nan)
        flags[start : start + len(p)] = (np.abs(low) < AMBIGUOUS).any(axis=1)
    return cell, value, flags


def write_set(folder: pathlib.Path, mesh_name: str, set_name: str, arrays: Dict[str, np.ndarray]) -> None:
    meta: Dict = {"mesh": mesh_name, "set": set_name, "arrays": {}}
    for key, a in arrays.items():
        file = f"{mesh_name}.{set_name}.{key}.bin"
        a.tofile(folder / file)
        meta["arrays"][key] = {"file": file, "dtype": a.dtype.str, "shape": list(a.shape)}
    (folder / f"{mesh_name}.{set_name}.json").write_text(json.dumps(meta))


@pytest.fixture(scope="session")
def generated_data(cli, tmp_path_factory) -> pathlib.Path:
    """A small oracle folder in the layout of ../shared/data, made now (see above)."""
    folder = tmp_path_factory.mktemp("generated-data")
    rng = np.random.default_rng(30)
    for name, shape, cells in GENERATED:
        path = folder / f"{name}.vtu"
        subprocess.run([cli, "gen", shape, "--cells", str(cells), "-q", "-o", str(path)], check=True)
        mesh = tetloc.read(path)
        lo, hi = np.array(mesh.bounds[0::2]), np.array(mesh.bounds[1::2])
        pick = rng.choice(mesh.n_tets, size=min(GENERATED_SET_SIZE, mesh.n_tets), replace=False)
        sets = {
            "centers": mesh.points64[mesh.tets[pick]].mean(axis=1),
            "random": rng.uniform(lo, hi, size=(GENERATED_SET_SIZE, 3)),
            "bbox": rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), size=(GENERATED_SET_SIZE, 3)),
        }
        for set_name, pts in sets.items():
            points = pts.astype(np.float32)
            cell, value, flags = oracle_answers(mesh, points)
            # A set that checks something: few points too close to call, some inside (and,
            # around the box, some outside).
            assert flags.mean() < 0.01 and (cell >= 0).mean() > 0.2, f"{name}.{set_name}"
            assert set_name != "bbox" or (cell < 0).any(), f"{name}.{set_name}"
            write_set(folder, name, set_name, {"points": points, "cell": cell, "value": value, "flags": flags})
    return folder
