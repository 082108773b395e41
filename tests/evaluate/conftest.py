"""Fixtures: the tiny model trained and exported once per test session (shared by name and
folder with tests/runtime and tests/export, so a full run builds it once)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def toy_model(tmp_path_factory):
    """A :class:`spacemesh.train.toy.ToyModel`."""
    pytest.importorskip("torch")
    pytest.importorskip("onnxscript")
    from spacemesh.train.toy import build_toy_model

    return build_toy_model(tmp_path_factory.getbasetemp() / "spacemesh-toy-model")
