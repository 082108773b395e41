"""Fixtures of the core tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def fitted():
    """An icosphere (subdivision 2) and embeddings fitted to it exactly."""
    from spacemesh.examples import icosphere
    from spacemesh.fitting import EmbeddingFitConfig, fit_mesh

    mesh = icosphere(2)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=400, threads=1))
    assert result.exact
    return mesh, result.embeddings
