"""Repair's in-painting with a local-point denoiser: the conditioning points reach it."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.examples import icosphere
from spacemesh.repair import Region, repair_mesh
from spacemesh.repair.inpaint import inpaint_tokens
from spacemesh.runtime import MeshGenerator
from spacemesh.topology import check_topology


def test_repair_runs_with_a_local_point_denoiser(local_model):
    generator = MeshGenerator.from_repository(local_model.directory, threads=1)
    assert generator.spec.local_points == 8
    mesh = icosphere(1)
    region = Region.sphere([0, 0, 1], 0.7)
    result = repair_mesh(mesh, region, generator, seed=1, steps=4)
    assert result.stats.tokens == generator.spec.max_vertices
    assert check_topology(result.mesh).is_closed_oriented_manifold
    again = repair_mesh(mesh, region, generator, seed=1, steps=4)
    assert np.array_equal(again.mesh.vertices, result.mesh.vertices)
    # without the points, the graph cannot run: the pass-through is what makes it work
    backend = generator.backend
    points = np.random.default_rng(0).uniform(-1, 1, (1, 300, 3)).astype(np.float32)
    volumes = backend.encode(points)
    steps = generator.spec.schedule.respaced(2)
    known, hole = np.zeros((4, 3)), np.zeros((generator.spec.max_vertices - 4, 3))
    inpaint_tokens(backend, volumes, known, hole, steps, method="ddim",
                   rng=np.random.default_rng(0), points=points)
    with pytest.raises(Exception, match="points"):
        inpaint_tokens(backend, volumes, known, hole, steps, method="ddim",
                       rng=np.random.default_rng(0))
