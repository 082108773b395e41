"""Fixtures: the shipped model (the tiny model, ``toy_model``, is tests/conftest.py's)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def shipped():
    """The shipped model's repository (one thread), loaded once per test module."""
    from spacemesh.runtime import ModelRepository
    from spacemesh.runtime.repository import default_model_dir

    if not default_model_dir().exists():
        pytest.skip("no shipped model in this checkout")
    return ModelRepository.load(threads=1)
