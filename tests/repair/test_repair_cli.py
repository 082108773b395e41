"""``spacemesh repair``: region options, output, and one-line errors (stand-in model)."""

from __future__ import annotations

import json

import pytest
from repair_testing import NoiseBackend, assert_closed_manifold, flat_shaded, make_spec
from typer.testing import CliRunner

from spacemesh.cli import _register
from spacemesh.cli.common import app
from spacemesh.cli.repair import region_from_options
from spacemesh.examples import icosphere
from spacemesh.io import load_mesh, save_mesh
from spacemesh.runtime import MeshGenerator

_register()  # every command, so that ``repair`` is a subcommand as in the real program


@pytest.fixture()
def fake_model(monkeypatch):
    def from_repository(cls, path=None, **kwargs):
        return cls(NoiseBackend(), make_spec(), name="noise")

    monkeypatch.setattr(MeshGenerator, "from_repository", classmethod(from_repository))


def test_region_options_map_to_the_json_forms():
    assert region_from_options("1,2,5-7", None, None, None) == {"faces": [1, 2, 5, 6, 7]}
    assert region_from_options(None, "4", None, None) == {"vertices": [4]}
    assert region_from_options(None, None, "0,0,1,0.5", None) == {
        "sphere": {"center": [0.0, 0.0, 1.0], "radius": 0.5}}
    assert region_from_options(None, None, None, "-1,-1,0,1,1,1") == {
        "box": {"min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 1.0]}}


def test_repair_writes_the_mesh_and_a_summary(fake_model, tmp_path):
    source, out = tmp_path / "ico.obj", tmp_path / "fixed.ply"
    mesh = icosphere(2)
    save_mesh(mesh, source)
    result = CliRunner().invoke(app, ["repair", str(source), "--sphere", "0,0,1,0.4", "-o",
                                      str(out), "--json", "--seed", "2", "--steps", "4"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["model"] == "noise" and summary["steps"] == 4 and summary["seed"] == 2
    fixed = load_mesh(out)
    assert fixed.n_faces == summary["faces"]
    assert_closed_manifold(fixed)
    result = CliRunner().invoke(app, ["repair", str(source), "--vertices", "0", "-o",
                                      str(tmp_path / "b.obj"), "--no-progress"])
    assert result.exit_code == 0 and "new vertices" in result.output


@pytest.mark.parametrize("args, message", [
    (["--faces", "1", "--vertices", "2"], "exactly one of"),
    ([], "exactly one of"),
    (["--sphere", "0,0,9,0.1"], "empty-region"),
    (["--faces", "0-319"], "whole-mesh-region"),
    (["--faces", "999"], "invalid-region"),
    (["--sphere", "1,2,3"], "expected 4 numbers"),
    (["--faces", "a"], "indices"),
])
def test_user_errors_are_one_line(fake_model, tmp_path, args, message):
    source = tmp_path / "ico.obj"
    save_mesh(icosphere(2), source)
    result = CliRunner().invoke(app, ["repair", str(source), *args, "-o",
                                      str(tmp_path / "o.obj")])
    assert result.exit_code == 2
    assert message in result.output


def test_weld_repairs_a_flat_shaded_glb(fake_model, tmp_path):
    source, out = tmp_path / "flat.glb", tmp_path / "fixed.obj"
    save_mesh(flat_shaded(icosphere(2)), source)
    args = ["repair", str(source), "--sphere", "0,0,1,0.5", "-o", str(out), "--no-progress"]
    refused = CliRunner().invoke(app, args)
    assert refused.exit_code == 2
    assert "defects-outside-region" in refused.output and "--weld" in refused.output
    result = CliRunner().invoke(app, [*args, "--weld", "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["welded_vertices"] == 3 * 320 - 162
    assert_closed_manifold(load_mesh(out))


@pytest.mark.parametrize("fault", ["moved", "dropped"])
def test_a_faulty_repair_is_never_written(fake_model, tmp_path, monkeypatch, fault):
    """The CLI runs the service's check (``verify_repair``) before it writes anything."""
    import spacemesh.cli.repair as repair_command
    from spacemesh.repair import repair_mesh
    from tests.service.service_testing import faulty_repair

    monkeypatch.setattr(repair_command, "REPAIR", faulty_repair(repair_mesh, fault))
    source, out = tmp_path / "ico.obj", tmp_path / "fixed.ply"
    save_mesh(icosphere(2), source)
    result = CliRunner().invoke(app, ["repair", str(source), "--sphere", "0,0,1,0.4", "-o",
                                      str(out), "--steps", "4", "--no-progress"])
    assert result.exit_code == 1, result.output
    assert "outside the grown region" in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_the_summary_says_what_was_done_about_crossings():
    from spacemesh.cli.repair import crossings_summary
    from spacemesh.repair import RepairStats

    assert crossings_summary(RepairStats(fill={"uncrossed_faces": 2})) == ""
    assert crossings_summary(RepairStats(fill={"regrown_faces": 3, "regrowths": 1})) == (
        ", 3 taken in where the new faces crossed")
    assert crossings_summary(RepairStats(fill={"regrown_faces": 0, "regrowths": 1})) == (
        ", new faces still cross (the region grown around them did not mend them)")
    assert crossings_summary(RepairStats(fill={"refilled_faces": 12, "regrown_faces": 3})) == (
        ", 12 faces made again and 3 taken in where the new faces crossed")
