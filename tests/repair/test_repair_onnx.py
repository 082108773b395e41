"""Repair with a real exported model (the tiny toy model, in onnxruntime)."""

from __future__ import annotations

import numpy as np
import pytest
from repair_testing import assert_closed_manifold, assert_outside_identical

from spacemesh.examples import icosphere, torus_grid
from spacemesh.repair import Region, repair_mesh

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def generator(toy_model):
    pytest.importorskip("onnxruntime")
    from spacemesh.runtime import MeshGenerator

    return MeshGenerator.from_repository(toy_model.repository, threads=1)


@pytest.mark.parametrize("make, region", [
    (lambda: icosphere(1), Region.sphere([0, 0, 1], 0.7)),
    (lambda: icosphere(3), Region.sphere([0, 0, 1], 0.3)),
    (lambda: torus_grid(20, 10, triangulate_every=4), Region.box([2, -0.5, -1], [4, 0.5, 1])),
])
def test_inpainting_with_an_exported_model(generator, make, region):
    mesh = make()
    result = repair_mesh(mesh, region, generator, seed=1)
    assert result.stats.tokens == generator.spec.max_vertices
    assert result.stats.known_vertices + result.stats.candidates <= result.stats.tokens
    assert_outside_identical(mesh, result)
    assert_closed_manifold(result.mesh)
    again = repair_mesh(mesh, region, generator, seed=1)
    assert np.array_equal(again.mesh.vertices, result.mesh.vertices)
    assert np.array_equal(again.mesh.face_indices, result.mesh.face_indices)
