"""``spacemesh eval`` end to end: a tiny model and the baselines on a 3-shape dataset."""

from __future__ import annotations

import csv

import pytest
from typer.testing import CliRunner

pytest.importorskip("pymeshlab")

from spacemesh.cli import _register
from spacemesh.cli.common import app

_register()  # every command, so that ``eval`` is a subcommand as in the real program

PNG = b"\x89PNG\r\n\x1a\n"


def test_eval_refuses_bad_arguments(tmp_path):
    runner = CliRunner()
    result = runner.invoke(
        app,
        ["eval", "--data", str(tmp_path / "nowhere"), "--out", str(tmp_path / "out"), "--no-model"],
    )
    assert result.exit_code == 2 and "nowhere" in result.output
    result = runner.invoke(
        app,
        [
            "eval",
            "--data",
            str(tmp_path),
            "--out",
            str(tmp_path),
            "--baselines",
            "psr,magic",
            "--no-model",
        ],
    )
    assert result.exit_code == 2 and "magic" in result.output
    result = runner.invoke(
        app,
        [
            "eval",
            "--data",
            str(tmp_path),
            "--out",
            str(tmp_path),
            "--model",
            str(tmp_path / "no-model"),
        ],
    )
    assert result.exit_code == 2


@pytest.mark.slow
def test_eval_end_to_end_with_a_tiny_model(toy_model, tmp_path):
    out = tmp_path / "report"
    result = CliRunner().invoke(
        app,
        [
            "eval",
            "--model",
            str(toy_model.repository),
            "--data",
            str(toy_model.data),
            "--split",
            "all",
            "--limit",
            "3",
            "--baselines",
            "psr,psr_star,bpa",
            "--out",
            str(out),
            "--gallery",
            "2",
            "--no-progress",
        ],
    )
    assert result.exit_code == 0, result.output
    table = (out / "table.md").read_text()
    for label in ("| Ours |", "| PSR |", "| PSR* |", "| BPA |", "| GT (resampled) |"):
        assert label in table
    assert "--model" in table  # the command that re-runs it
    rows = list(csv.DictReader(open(out / "per_shape.csv")))
    assert len(rows) == 3 * 5
    assert {r["method"] for r in rows} == {"ours", "psr", "psr_star", "bpa", "gt"}
    for name in ("histograms.png", "gallery.png"):
        assert (out / name).read_bytes()[:8] == PNG
