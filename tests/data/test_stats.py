"""Statistics of a dataset, and the ``data synth`` / ``data stats`` command lines."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

import spacemesh.cli.data  # noqa: F401  (registers the ``data`` commands)
from spacemesh.cli.common import app
from spacemesh.data.stats import collect_stats, plot_stats


@pytest.fixture(scope="module")
def planar_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("planar")
    result = CliRunner().invoke(
        app,
        [
            "data",
            "synth",
            "--out",
            str(out),
            "--count",
            "5",
            "--style",
            "planar",
            "--vertices",
            "8:200",
            "--points",
            "16",
            "--seed",
            "2",
            "--no-progress",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "shapes stored" in result.output
    return out


def test_stats_collects_and_plots(planar_dir, tmp_path):
    stats = collect_stats(planar_dir)
    assert stats.count == json.loads((planar_dir / "manifest.json").read_text())["counts"]["stored"]
    assert stats.count >= 4
    summary = stats.summary()
    assert summary["style"] == "planar" and sum(summary["splits"].values()) == stats.count
    assert set(summary["face_degrees"]) >= {"4"}
    png = plot_stats(stats, tmp_path / "s.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_stats_cli(planar_dir):
    result = CliRunner().invoke(app, ["data", "stats", str(planar_dir)])
    assert result.exit_code == 0, result.output
    for heading in ("vertices:", "faces:", "face degrees:", "genus:"):
        assert heading in result.output
    assert (planar_dir / "stats.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--vertices", "12"], "MIN:MAX"),
        (["--vertices", "64:8"], "MIN <= MAX"),
        (["--style", "voxel"], "unknown --style"),
        (["--workers", "0"], "--workers must be at least 1"),
    ],
)
def test_synth_cli_bad_input_is_one_line(tmp_path, args, message):
    result = CliRunner().invoke(
        app, ["data", "synth", "--out", str(tmp_path / "x"), "--count", "1", *args]
    )
    assert result.exit_code == 2
    assert message in result.output and result.output.strip().count("\n") == 0
    assert "Traceback" not in result.output


def test_stats_cli_missing_manifest(tmp_path):
    result = CliRunner().invoke(app, ["data", "stats", str(tmp_path)])
    assert result.exit_code == 2 and "manifest.json" in result.output
