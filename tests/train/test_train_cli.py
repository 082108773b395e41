"""``spacemesh train``'s options for diffusion-only runs: the encoder cache, the
augmentation, a dataset mix and the checkpoint timer, and their one-line refusals."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("torch")

from typer.testing import CliRunner

from spacemesh.cli import _register
from spacemesh.cli.common import app
from spacemesh.train.toy import make_toy_dataset


def _train(*options: str):
    _register()
    return CliRunner().invoke(app, ["train", *options], env={"COLUMNS": "200"})


def test_help_names_the_options():
    result = _train("--help")
    assert result.exit_code == 0
    for flag in ("--diffusion-only", "--encoder-cache", "--augment", "--mix",
                 "--checkpoint-minutes", "--init-from", "--base", "--warm-start"):
        assert flag in result.output


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--encoder-cache", "2"], "--encoder-cache applies to --diffusion-only runs"),
        (["--diffusion-only"], "--diffusion-only freezes a trained encoder"),
        (["--augment", "wild"], "unknown augmentation 'wild'"),
        (["--resume", "--augment", "realistic"], "apply to new runs"),
        (["--warm-start"], "--warm-start applies to --diffusion-only runs"),
        (["--diffusion-only", "--init-from", "x", "--warm-start"], "give --base"),
    ],
)
def test_bad_combinations_exit_2_with_one_line(toy_data, tmp_path, options, message):
    result = _train("--config", "tiny", "--data", str(toy_data), "--out", str(tmp_path / "r"),
                    *options)
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert not (tmp_path / "r").exists()


def test_a_diffusion_only_run_from_the_command_line(toy_model, tmp_path):
    other = make_toy_dataset(tmp_path / "other", count=10, seed=3)
    run = tmp_path / "run"
    result = _train("--config", "tiny-local", "--data", str(toy_model.data), "--out", str(run),
                    "--base", str(toy_model.repository), "--diffusion-only",
                    "--encoder-cache", "2", "--augment", "realistic", "--mix", str(other),
                    "--checkpoint-minutes", "5", "--steps", "1", "--threads", "1",
                    "--no-progress")
    assert result.exit_code == 0, result.output
    train = json.loads((run / "config.json").read_text())["train"]
    assert train["diffusion_only"] and train["encoder_cache"] == 2
    assert train["augment"] == "realistic" and train["checkpoint_minutes"] == 5
    assert json.loads((run / "data.json").read_text())["mix"][0]["dataset"] == "other"
    assert (run / "checkpoints" / "last.pt").is_file()
