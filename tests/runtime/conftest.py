"""Fixtures: a tiny model trained and exported once per test session via the CLI, and
the shipped model."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def toy_model(tmp_path_factory):
    """A :class:`spacemesh.train.toy.ToyModel` (shared by tests/export and tests/runtime)."""
    pytest.importorskip("torch")
    pytest.importorskip("onnxscript")
    from spacemesh.train.toy import build_toy_model

    return build_toy_model(tmp_path_factory.getbasetemp() / "spacemesh-toy-model")


@pytest.fixture(scope="module")
def shipped():
    """The shipped model's repository (one thread), loaded once per test module."""
    from spacemesh.runtime import ModelRepository
    from spacemesh.runtime.repository import default_model_dir

    if not default_model_dir().exists():
        pytest.skip("no shipped model in this checkout")
    return ModelRepository.load(threads=1)
