"""``spacemesh fit-collection`` end to end on three tiny meshes: training to exact, the
JSON keys, resume, decoding back to files, the gallery, and one-line errors."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

pytest.importorskip("torch")

from spacemesh.cli import _register
from spacemesh.cli.common import app
from spacemesh.fitting.collection_data import prepare_mesh
from spacemesh.io import load_mesh, save_mesh
from spacemesh.mesh import PolygonMesh
from tests.factories import cube_quads, prism, torus_grid

_register()

#: The keys of ``spacemesh fit --json``.
FIT_KEYS = {"exact", "iterations", "seconds", "n_vertices", "n_faces", "edge_f1", "next_accuracy"}


def run(*args: str):
    return CliRunner().invoke(app, ["fit-collection", *args])


@pytest.fixture(scope="module")
def mesh_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("meshes")
    paths = []
    for name, mesh in [("cube.obj", cube_quads()), ("prism.obj", prism(5)),
                       ("torus.obj", torus_grid(4, 3))]:
        save_mesh(mesh, folder / name)
        paths.append(str(folder / name))
    return paths


@pytest.fixture(scope="module")
def trained(mesh_files, tmp_path_factory):
    """A run trained until every mesh decodes exactly (exit 0)."""
    out = tmp_path_factory.mktemp("run") / "run"
    result = run(*mesh_files, "--out", str(out), "--json", "--threads", "1",
                 "--max-steps", "400")
    return out, result


def test_trains_to_exact_with_fit_keys(trained):
    out, result = trained
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert FIT_KEYS <= set(summary)
    assert summary["exact"] == 1.0 and summary["n_exact"] == 3
    assert summary["edge_f1"] == 1.0 and summary["next_accuracy"] == 1.0
    assert summary["iterations"] < 400  # stopped when every mesh was exact
    assert len(summary["meshes"]) == 3
    for m in summary["meshes"]:
        assert FIT_KEYS | {"file", "vertex_l2"} <= set(m)
        assert m["exact"] is True and m["vertex_l2"] <= 5e-4  # the early stop's target
    assert summary["n_vertices"] == 8 + 10 + 12
    assert (out / "gallery.png").stat().st_size > 1000
    assert json.loads((out / "scores.json").read_text())["n_exact"] == 3


def test_decode_writes_the_meshes(trained, mesh_files, tmp_path):
    out, _ = trained
    result = run("--decode", str(out), "-o", str(tmp_path / "decoded"), "--threads", "1")
    assert result.exit_code == 0, result.output
    for path in mesh_files:
        name = path.rsplit("/", 1)[-1]
        decoded = load_mesh(tmp_path / "decoded" / name)
        original = load_mesh(path)
        # same faces in the collection's (z-y-x) vertex order, positions near the original
        assert decoded.face_key_set() == prepare_mesh(original, name).mesh.face_key_set()
        assert abs(decoded.vertices.max(0) - original.vertices.max(0)).max() < 0.3


def test_resume_continues_the_step_count(mesh_files, tmp_path):
    import torch

    out = tmp_path / "run"
    first = run(*mesh_files, "--out", str(out), "--json", "--threads", "1", "--max-steps", "3")
    assert first.exit_code == 1, first.output  # not exact after 3 steps
    assert json.loads(first.stdout.strip().splitlines()[-1])["iterations"] == 3
    again = run(*mesh_files, "--out", str(out), "--threads", "1", "--max-steps", "3")
    assert again.exit_code == 2 and "--resume" in again.stderr
    resumed = run(*mesh_files, "--out", str(out), "--json", "--threads", "1",
                  "--max-steps", "5", "--resume", "--lr", "1e-4", "--code-lr", "2e-3")
    summary = json.loads(resumed.stdout.strip().splitlines()[-1])
    assert summary["iterations"] == 5
    # the resumed steps ran at this call's learning rates, not the checkpoint's
    groups = torch.load(out / "checkpoint.pt", weights_only=False)["optimizer"]["param_groups"]
    assert [(g["base"], g["lr"]) for g in groups] == [(2e-3, 2e-3 * 5 / 20), (1e-4, 1e-4 * 5 / 20)]
    assert (out / "log.csv").read_text().count("\n") == 1 + 5
    other = run(*mesh_files[:2], "--out", str(out), "--threads", "1", "--max-steps", "6",
                "--resume")
    assert other.exit_code == 2 and "other meshes" in other.stderr


def _open_box(path):
    cube = cube_quads()
    save_mesh(PolygonMesh.from_faces(cube.vertices, cube.faces[1:]), path)


@pytest.mark.parametrize(
    ("make_args", "message"),
    [
        (lambda p, files: [str(p / "missing.obj"), "--out", str(p / "r")], "no such file"),
        (lambda p, files: [str(p / "open.obj"), "--out", str(p / "r")], "not a closed"),
        (lambda p, files: [*files, "--out", str(p / "r"), "--max-vertices", "9"],
         "more than the collection's limit of 9"),
        (lambda p, files: ["--out", str(p / "r")], "no MESHES"),
        (lambda p, files: [*files], "--out RUN is required"),
        (lambda p, files: [*files, "--out", str(p / "r"), "--resume"], "no checkpoint"),
        (lambda p, files: ["--decode", str(p)], "-o DIR"),
        (lambda p, files: ["--decode", str(p), "-o", str(p / "d")], "not a fit-collection run"),
        (lambda p, files: [*files, "--out", str(p / "r"), "--device", "tpu"], "cpu or cuda"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, mesh_files, make_args, message):
    _open_box(tmp_path / "open.obj")
    result = run(*make_args(tmp_path, mesh_files), "--threads", "1")
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.output


def test_the_position_loss_weighs_each_mesh_by_its_own_vertices():
    import torch

    from spacemesh.fitting.collection import _position_loss

    n = 100
    target = torch.zeros(2, n, 4)
    target[..., 3] = -1.0
    target[0, :4, 3] = 1.0  # a 4-vertex mesh
    target[1, :80, 3] = 1.0  # an 80-vertex one
    mask = target[..., 3].clone()  # the mask channel right
    positions = torch.zeros(2, n, 3)
    positions[0, :4] = 0.3  # the small mesh's vertices off by 0.3 in each coordinate
    positions[:, 90:] = 5.0  # the padding's positions are free
    per_vertex = _position_loss(positions, mask, target, per_vertex=True)
    assert per_vertex.item() == pytest.approx(0.5 * 0.09)  # its own MSE, halved by the mean
    positions[0, :4] = 0.0
    positions[1, :80] = 0.3  # the same error on the large mesh costs the same
    assert _position_loss(positions, mask, target, per_vertex=True).item() == pytest.approx(
        0.5 * 0.09)
    mask[1, 95] = 0.0  # a padding slot's mask wrong: the mask's mean over all slots
    assert _position_loss(positions, mask, target, per_vertex=True).item() == pytest.approx(
        0.5 * 0.09 + 1.0 / (2 * n))
    # over all slots (the earlier runs): the padding's zeros dilute the positions
    positions[:, 90:] = 0.0
    mask[1, 95] = -1.0
    positions[1, :80] = 0.0
    positions[0, :4] = 0.3
    assert _position_loss(positions, mask, target, per_vertex=False).item() == pytest.approx(
        4 * 3 * 0.09 / (2 * n * 4))
