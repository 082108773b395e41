"""``spacemesh fit`` end to end: exit codes, JSON, the decoded file, one-line errors."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

pytest.importorskip("torch")

from spacemesh.cli import _register
from spacemesh.cli.common import app
from spacemesh.io import load_mesh, save_mesh
from spacemesh.mesh import PolygonMesh
from tests.factories import icosphere, torus_grid

_register()


@pytest.fixture
def torus_file(tmp_path):
    path = tmp_path / "torus.obj"
    save_mesh(torus_grid(8, 5, 3), path)
    return path


def run(*args: str):
    return CliRunner().invoke(app, ["fit", *args])


@pytest.mark.parametrize("init", ["random", "positions"])
def test_fit_writes_the_exact_mesh_and_json(torus_file, tmp_path, init):
    out = tmp_path / "decoded.ply"
    result = run(str(torus_file), "--json", "--init", init, "--threads", "1", "-o", str(out))
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert summary["exact"] is True and summary["n_vertices"] == 40
    assert load_mesh(out).face_key_set() == load_mesh(torus_file).face_key_set()


def test_budget_exhausted_exits_1(torus_file):
    result = run(str(torus_file), "--max-iters", "1", "--threads", "1")
    assert result.exit_code == 1
    assert "NOT exact after 1 iterations" in result.stdout


@pytest.mark.parametrize(
    ("make_args", "message"),
    [
        (lambda p: [str(p.parent / "missing.obj")], "no such file"),
        (lambda p: [str(p), "--init", "positions", "--distance", "dot"], "space coordinates"),
        (lambda p: [str(p), "-o", str(p.parent / "nowhere" / "x.obj")], "no such directory"),
    ],
)
def test_bad_arguments_are_one_line(torus_file, make_args, message):
    result = run(*make_args(torus_file))
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.output


def test_open_and_malformed_meshes_are_refused(tmp_path):
    sphere = icosphere(1)
    open_mesh = PolygonMesh.from_faces(sphere.vertices, [f.tolist() for f in sphere.faces[1:]])
    save_mesh(open_mesh, tmp_path / "open.obj")
    (tmp_path / "broken.obj").write_text("v 0 0 0\nf 1 2 3\n")
    for name in ("open.obj", "broken.obj"):
        result = run(str(tmp_path / name))
        assert result.exit_code == 2, (name, result.output)
        assert len(result.stderr.strip().splitlines()) == 1 and name in result.stderr
