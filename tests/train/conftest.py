"""Fixtures of the training tests: a toy dataset made in well under a second, and a tiny
local-point denoiser trained on the toy model and exported beside it."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def toy_data(tmp_path_factory):
    from spacemesh.train.toy import make_toy_dataset

    return make_toy_dataset(tmp_path_factory.mktemp("toy") / "data", count=30, seed=0)


@pytest.fixture(scope="session")
def local_model(toy_model, tmp_path_factory):
    """A 2-step diffusion-only ``tiny-local`` run on a copy of the tiny model (``base``;
    ``toy_model`` of tests/conftest.py), exported as a model version (``directory``): its
    ``denoiser.onnx`` takes ``points``."""
    import shutil
    from types import SimpleNamespace

    torch = pytest.importorskip("torch")
    from spacemesh.export.repository import export_run
    from spacemesh.nn.config import get_config
    from spacemesh.train.loop import TrainOptions, train

    folder = tmp_path_factory.mktemp("local-model")
    base = folder / "models" / "spacemesh-tiny" / "1"
    shutil.copytree(toy_model.repository, base)
    config = get_config("tiny-local").with_train(
        diffusion_only=True, val_every=2, checkpoint_every=2, val_shapes=2, batch_size=3)
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        run = folder / "local"
        train(TrainOptions(config=config, data=toy_model.data, out=run, steps=2,
                           progress=False, base=base), log=lambda _m: None)
        directory = export_run(run, folder / "models", name="spacemesh-tiny-local", threads=1)
    finally:
        torch.set_num_threads(before)
    return SimpleNamespace(base=base, run=run, directory=directory, data=toy_model.data)


@pytest.fixture
def one_thread():
    """torch on one thread for the test, as it was afterwards."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
