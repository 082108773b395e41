"""Fixtures: a tiny model trained and exported once per test session via the CLI."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def toy_model(tmp_path_factory):
    """A :class:`spacemesh.train.toy.ToyModel` (shared by tests/export and tests/runtime)."""
    pytest.importorskip("torch")
    pytest.importorskip("onnxscript")
    from spacemesh.train.toy import build_toy_model

    return build_toy_model(tmp_path_factory.getbasetemp() / "spacemesh-toy-model")
