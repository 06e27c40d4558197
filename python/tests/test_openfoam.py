"""OpenFOAM cases from Python (issue 35): opened through the ``.foam`` file or the folder, the
time directories as ``Mesh.times`` and ``field(name, step=)``, and the cell-type refusal that
sends polyhedra to the file readers."""

from __future__ import annotations

import pathlib
import shutil

import numpy as np
import pytest

import tetloc


@pytest.fixture()
def case(data_dir, tmp_path) -> pathlib.Path:
    """``poly/octpoly_s_case`` copied, with a time ``2`` holding 3·lin beside ``1`` (2·lin)."""
    dst = tmp_path / "octpoly"
    shutil.copytree(data_dir / "poly" / "octpoly_s_case", dst)
    text = (dst / "0" / "lin").read_text()
    head, body = text.split("(", 1)
    values = [float(v) for v in body.split(")", 1)[0].split()]
    (dst / "2").mkdir()
    (dst / "2" / "lin").write_text(
        head.replace('location    "0"', 'location    "2"') + "(\n" + "\n".join(repr(3 * v) for v in values) + "\n)\n;\n"
    )
    return dst


def test_steps_are_the_time_directories(case):
    for path in [case, case / "octpoly_s.foam"]:
        mesh = tetloc.read(path)
        assert mesh.times == [1.0, 2.0], "the zero time is skipped, as ParaView does"
        assert mesh.n_cells == 289
        assert mesh.info()["mesh"]["cell_types"] == {"hexahedron": 257, "polyhedron": 32}
        first, second = mesh.field("lin", step=0), mesh.field("lin", step=1)
        np.testing.assert_array_equal(mesh.field("lin"), first)
        np.testing.assert_allclose(second, 1.5 * first, rtol=1e-14)
    with pytest.raises(ValueError, match=r"out of range"):
        mesh.field("lin", step=2)


def test_a_field_missing_at_a_time_names_the_directory(case):
    (case / "2" / "lin").rename(case / "2" / "other")
    mesh = tetloc.read(case)
    with pytest.raises(ValueError, match=r"2: has no field 'lin' \(time 1 has it"):
        mesh.field("lin", step=1)


def test_folders_that_are_not_cases_are_refused(tmp_path):
    with pytest.raises(IsADirectoryError, match="not an OpenFOAM case"):
        tetloc.read(tmp_path)


def test_polyhedra_as_cell_arrays_say_where_they_are_read():
    with pytest.raises(ValueError, match=r"carry no faces: tetloc reads them from .vtu and .vtk files and OpenFOAM cases") as e:
        tetloc.Mesh(np.eye(8, 3), {42: [[0, 1, 2, 3]]})
    assert "it reads volume cells:" in str(e.value) and "polyhedron," not in str(e.value)
