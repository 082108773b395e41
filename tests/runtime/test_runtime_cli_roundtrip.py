"""Train, export (the session fixture does both through the CLI) and generate via the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from spacemesh.io import load_mesh
from spacemesh.topology import check_topology

CLI = [sys.executable, "-c", "from spacemesh.cli import main; main()"]
#: Fit report fields that only a tolerance request has.
TOLERANCE_FIELDS = {"tolerance", "tolerance_met"}


def test_train_export_generate_round_trip(toy_model, tmp_path):
    points = tmp_path / "cloud.xyz"
    d = np.random.default_rng(1).normal(size=(256, 3))
    np.savetxt(points, 5.0 * d / np.linalg.norm(d, axis=1, keepdims=True) + 1.0)
    out = tmp_path / "mesh.obj"
    done = subprocess.run(
        [*CLI, "generate", str(points), "-o", str(out), "--model", str(toy_model.repository),
         "--seed", "4", "--steps", "4", "--threads", "1", "--json"],
        capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout)
    assert summary["steps"] == 4 and summary["model"] == "spacemesh-tiny"
    assert out.is_file()
    if summary["faces"]:  # an untrained toy model may decode to the empty mesh
        mesh = load_mesh(out)
        assert mesh.n_faces == summary["faces"]
        assert check_topology(mesh).is_closed_oriented_manifold


def test_generate_reports_user_errors(toy_model, tmp_path):
    done = subprocess.run([*CLI, "generate", str(tmp_path / "missing.xyz"), "-o",
                           str(tmp_path / "m.obj"), "--model", str(toy_model.repository)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "no such file" in done.stderr
    cloud = tmp_path / "c.xyz"
    np.savetxt(cloud, np.random.default_rng(0).normal(size=(20, 3)))
    done = subprocess.run([*CLI, "generate", str(cloud), "-o", str(tmp_path / "m.obj"),
                           "--model", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "manifest.json" in done.stderr
    pytest.importorskip("onnxruntime")


def test_generate_options_and_fit_report(toy_model, tmp_path):
    from spacemesh.geometry.report import FitReport

    points = tmp_path / "cloud.xyz"
    d = np.random.default_rng(2).normal(size=(150, 3))
    np.savetxt(points, d / np.linalg.norm(d, axis=1, keepdims=True))
    out = tmp_path / "mesh.obj"
    done = subprocess.run(
        [*CLI, "generate", str(points), "-o", str(out), "--model", str(toy_model.repository),
         "--seed", "3", "--start", "points", "--start-time", "0", "--target-vertices", "60",
         "--samples", "2", "--raw", "--threads", "1", "--json"],
        capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout)
    assert (summary["start"], summary["start_time"], summary["target_vertices"],
            summary["samples"], summary["raw"]) == ("points", 0.0, 60, 2, True)
    assert [seed for seed, _ in summary["sample_scores"]] == [3, 4]
    assert summary["seed"] in (3, 4)
    assert summary["surface"] == "closed"  # raw: the closed decode, no decision
    assert set(summary["fit"]) == (set(FitReport.__dataclass_fields__) - TOLERANCE_FIELDS
                                   - {"open_surface", "unsupported_area"})
    assert summary["fit"]["n_points"] == 150
    fit = summary["fit"]
    plain = subprocess.run([*CLI, "generate", str(points), "-o", str(out), "--model",
                            str(toy_model.repository), "--seed", str(summary["seed"]),
                            "--start", "points", "--start-time", "0", "--target-vertices", "60",
                            "--raw", "--threads", "1"],
                           capture_output=True, text=True, timeout=120)
    assert plain.returncode == 0, plain.stderr[-3000:]
    piece = "piece" if fit["pieces"] == 1 else "pieces"
    assert (f"; {fit['pieces']} {piece} (the points: {fit['points_pieces']}), "
            f"genus {fit['genus']}") in plain.stdout
    assert f"; the points: noise {100 * fit['points_noise']:.2g}% of the diagonal" in plain.stdout


@pytest.mark.parametrize(("flags", "message"), [
    (["--start", "bogus"], "--start: start must be one of noise, points"),
    (["--start", "noise", "--start-time", "0.5"], "--start-time: start_time applies to"),
    (["--start", "points", "--start-time", "2"], "--start-time: start_time must be in [0, 1]"),
    (["--start", "points", "--target-vertices", "3"], "--target-vertices: target_vertices "
                                                      "must be in 4..10000, not 3"),
    (["--start", "points", "--target-vertices", "20000"], "not 20000"),
    (["--samples", "0"], "--samples: samples must be in 1..16, not 0"),
    (["--samples", "17"], "--samples: samples must be in 1..16, not 17"),
    (["--sampler", "euler"], "--sampler: sampler must be one of"),
])
def test_generate_option_errors_are_one_line(toy_model, tmp_path, flags, message):
    from typer.testing import CliRunner

    from spacemesh.cli import _register, app

    _register()
    cloud = tmp_path / "c.xyz"
    np.savetxt(cloud, np.random.default_rng(0).normal(size=(40, 3)))
    out = tmp_path / "m.obj"
    result = CliRunner().invoke(app, ["generate", str(cloud), "-o", str(out), "--model",
                                      str(toy_model.repository), "--no-progress", *flags])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("spacemesh: error: "), result.stderr
    assert message in lines[0]
    assert not out.exists()


@pytest.mark.parametrize(("args", "message"), [
    (["generate", "--seed", "1e3"], "--seed: seed must be an integer (digits only, no "
                                    "fraction or exponent), not '1e3'"),
    (["generate", "--seed", "1.0"], "--seed: seed must be an integer"),
    (["generate", "--samples", "2.0"], "--samples: samples must be an integer"),
    (["generate", "--target-vertices", "500.0"], "--target-vertices: target_vertices must "
                                                 "be an integer"),
    (["generate", "--steps", "4.0"], "--steps: steps must be an integer"),
    (["generate", "--tolerance", "nan"], "--tolerance: tolerance must be a number"),
    (["repair", "--faces", "1", "--seed", "1e3"], "--seed: seed must be an integer"),
    (["repair", "--faces", "1", "--steps", "2.0"], "--steps: steps must be an integer"),
    (["repair", "--faces", "1", "--max-growth", "2"], "--max-growth: max_growth must be in "
                                                      "0..1, not 2.0"),
])
def test_option_types_are_the_services_and_one_line(tmp_path, args, message):
    """Both commands read option flags as text and parse them by the service's rule
    (``spacemesh.runtime.options.parse_value``), before any file or model is read: an
    integral float or an exponent is refused, never converted (not click's usage box)."""
    command, *flags = args
    done = subprocess.run([*CLI, command, str(tmp_path / "missing.ply"), "-o",
                           str(tmp_path / "m.obj"), *flags],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("spacemesh: error: "), done.stderr
    assert message in lines[0]


def _flat_cloud() -> np.ndarray:
    xy = np.random.default_rng(3).normal(size=(200, 2))
    return np.column_stack([xy, np.zeros(200)])


@pytest.mark.parametrize(("points", "kind"), [
    (np.random.default_rng(0).normal(size=(1, 3)), "too-few-points"),
    (np.random.default_rng(0).normal(size=(3, 3)), "too-few-points"),
    (np.random.default_rng(0).normal(size=(10, 3)), "too-few-points"),
    (_flat_cloud(), "degenerate-geometry"),
])
def test_generate_refuses_what_the_service_refuses(toy_model, tmp_path, points, kind):
    """The CLI checks clouds with the service's function and limits: 1, 3 or 10 points,
    or a flat cloud, are one line and exit code 2 (they once made a closed mesh)."""
    from spacemesh.runtime.cloud import CloudError, validate_cloud

    with pytest.raises(CloudError) as info:  # what the service answers with a 422
        validate_cloud(points)
    assert info.value.kind == kind
    cloud = tmp_path / "cloud.xyz"
    np.savetxt(cloud, points)
    out = tmp_path / "mesh.obj"
    done = subprocess.run([*CLI, "generate", str(cloud), "-o", str(out), "--model",
                           str(toy_model.repository), "--threads", "1", "--no-progress"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr.count("\n") == 1 and f"({kind})" in done.stderr
    assert str(info.value) in done.stderr
    assert not out.exists()


def test_the_cli_searches_a_tolerance_and_refuses_it_with_a_target(toy_model, tmp_path):
    from spacemesh.geometry.report import FitReport

    points = tmp_path / "points.xyz"
    d = np.random.default_rng(2).normal(size=(150, 3))
    np.savetxt(points, d / np.linalg.norm(d, axis=1, keepdims=True))
    out = tmp_path / "mesh.obj"
    base = [*CLI, "generate", str(points), "-o", str(out), "--model", str(toy_model.repository),
            "--seed", "3", "--start", "points", "--threads", "1", "--tolerance", "0.05"]
    done = subprocess.run([*base, "--json"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout)
    fit = summary["fit"]
    assert summary["tolerance"] == 0.05 and summary["target_vertices"] is None
    assert set(fit) == set(FitReport.__dataclass_fields__)
    assert fit["tolerance_met"] == (fit["points_to_mesh_mean_rel"] <= 0.05)
    plain = subprocess.run(base, capture_output=True, text=True, timeout=300)
    assert plain.returncode == 0, plain.stderr[-3000:]
    assert f", tolerance 0.05 {'met' if fit['tolerance_met'] else 'not met'}" in plain.stdout
    both = subprocess.run([*base, "--target-vertices", "60"], capture_output=True, text=True,
                          timeout=120)
    assert both.returncode == 2 and "Traceback" not in both.stderr
    assert both.stderr.strip().count("\n") == 0 and "--tolerance" in both.stderr


def test_the_progress_line_names_the_stage_that_is_running(tmp_path):
    """A default generate (the shipped model) names its stages on stderr, the geometry
    stage included, rather than a step count that stands still (issue 46)."""
    points = tmp_path / "cloud.xyz"
    d = np.random.default_rng(5).normal(size=(2048, 3))
    np.savetxt(points, d / np.linalg.norm(d, axis=1, keepdims=True) * [1.0, 0.8, 0.6])
    done = subprocess.run([*CLI, "generate", str(points), "-o", str(tmp_path / "m.obj"),
                           "--threads", "1", "--progress"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    shown = [part.strip() for part in done.stderr.replace("\r", "\n").splitlines()]
    names = {part.split(" [")[0].split(" ")[0] for part in shown if part.endswith("]")}
    assert {"encoder", "connectivity", "decode", "geometry", "report"} <= names, shown
    assert "step" not in done.stderr.replace("sampler step", "")


def test_generate_with_a_budget_refuses_what_the_service_would(toy_model, tmp_path):
    """``--budget-s`` runs the service's cost check before any work: over it, one line
    naming the option to lower (too-expensive) and exit code 2; within it, the mesh."""
    from typer.testing import CliRunner

    from spacemesh.cli import _register, app

    _register()
    cloud = tmp_path / "c.xyz"
    np.savetxt(cloud, np.random.default_rng(0).normal(size=(300, 3)))
    out = tmp_path / "m.obj"
    base = ["generate", str(cloud), "-o", str(out), "--model", str(toy_model.repository),
            "--no-progress", "--threads", "1", "--budget-s", "5"]
    result = CliRunner().invoke(app, [*base, "--start", "points",
                                      "--target-vertices", "10000"])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("spacemesh: error: "), result.stderr
    assert "lower target_vertices" in lines[0] and lines[0].endswith("(too-expensive)")
    assert not out.exists()
    assert CliRunner().invoke(app, base).exit_code == 0 and out.exists()
