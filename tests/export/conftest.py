"""Fixtures: a connectivity-only run on the tiny model (``toy_model``, tests/conftest.py)."""

from __future__ import annotations

import shutil

import pytest


def tiny_config(**changes):
    """``tiny`` with validation and checkpoints every 2 steps, on batches of 3."""
    from spacemesh.nn.config import get_config

    return get_config("tiny").with_train(val_every=2, checkpoint_every=2, val_shapes=2,
                                         batch_size=3, **changes)


def invoke_train(toy_model, out, *options: str):
    """``spacemesh train --config tiny`` on the toy data into ``out``, through the CLI."""
    from typer.testing import CliRunner

    from spacemesh.cli import _register
    from spacemesh.cli.common import app

    _register()
    return CliRunner().invoke(app, ["train", "--config", "tiny", "--data", str(toy_model.data),
                                    "--out", str(out), *options])



@pytest.fixture(scope="session")
def base_run(toy_model, tmp_path_factory):
    """A copy of the toy model as the base, and a 2-step connectivity-only run on it."""
    import torch

    from spacemesh.train.loop import TrainOptions, train

    folder = tmp_path_factory.mktemp("base-run")
    base = folder / "models" / "spacemesh-tiny" / "1"
    shutil.copytree(toy_model.repository, base)
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        run = folder / "run"
        train(TrainOptions(config=tiny_config(), data=toy_model.data, out=run, steps=2,
                           progress=False, base=base, threads=1), log=lambda m: None)
    finally:
        torch.set_num_threads(before)
    return base, run


@pytest.fixture(scope="session")
def exported_base_run(base_run):
    """``base_run``'s connectivity-only model exported next to its base (one export,
    shared by the export and the fine-tuning tests): its version folder."""
    from spacemesh.export.repository import export_run

    base, run = base_run
    return export_run(run, base.parent.parent, name="spacemesh-tiny-conn", version=1,
                      threads=1)
