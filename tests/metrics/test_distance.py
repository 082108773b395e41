"""Chamfer distance, F1, IN and the sampling frame."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere
from spacemesh.metrics import (
    Reference,
    apply_normalisation,
    chamfer_f1,
    inaccurate_normals,
    normalisation,
    sample_mesh,
    score_mesh,
)
from spacemesh.primitives import flip_faces


def unit_cube():
    """The cube [-1, 1]^3 (already in the metric frame)."""
    cube = cube_quads(2.0)
    return cube.with_vertices(cube.vertices - 1.0)


def test_chamfer_of_shifted_grid_is_twice_the_squared_shift():
    grid = np.stack(np.meshgrid(*[np.arange(5.0)] * 3), -1).reshape(-1, 3)
    scores = chamfer_f1(grid + np.array([0.1, 0, 0]), grid, threshold=0.2)
    assert scores.chamfer == pytest.approx(2 * 0.1**2)
    assert scores.pred_to_gt == pytest.approx(scores.gt_to_pred)
    assert scores.f1 == 1.0
    assert chamfer_f1(grid + np.array([0.1, 0, 0]), grid, threshold=0.05).f1 == 0.0


def test_mesh_against_itself_scores_perfectly():
    cube = unit_cube()
    row = score_mesh(cube, Reference.from_mesh(cube, seed=3), seed=3)
    assert row["cd"] == 0.0 and row["f1"] == 1.0
    assert row["ecd"] == 0.0 and row["ef1"] == 1.0
    assert row["in"] == 0.0 and row["valid"]
    assert row["edge_length_w1"] == 0.0 and row["corner_angle_w1"] == 0.0
    assert row["degrees"] == "4:6"


def test_chamfer_grows_with_an_offset():
    sphere = icosphere(3)
    reference = Reference.from_mesh(sphere, seed=0)
    shifts = [np.array([d, 0.0, 0.0]) for d in (0.0, 0.05, 0.1, 0.2)]
    cds = [
        score_mesh(sphere.with_vertices(sphere.vertices + s), reference, seed=1)["cd"]
        for s in shifts
    ]
    assert all(a < b for a, b in itertools.pairwise(cds))
    # resampling alone costs about the sampling noise, far below a 0.2 offset
    assert cds[0] < 2e-3 < cds[-1]


def test_inaccurate_normals_of_a_flipped_mesh_is_all():
    sphere = icosphere(3)
    gt = sample_mesh(sphere, 5000, seed=0)
    assert inaccurate_normals(sample_mesh(sphere, 5000, seed=1), gt) < 0.02
    assert inaccurate_normals(sample_mesh(flip_faces(sphere), 5000, seed=1), gt) > 0.99


def test_samples_are_seeded_and_on_the_surface():
    cube = unit_cube()
    a, b = sample_mesh(cube, 1000, seed=7), sample_mesh(cube, 1000, seed=7)
    np.testing.assert_array_equal(a.points, b.points)
    assert np.allclose(np.abs(a.points).max(axis=1), 1.0, atol=1e-6)  # on a face of the cube
    assert np.allclose(np.linalg.norm(a.normals, axis=1), 1.0, atol=1e-5)
    assert len(sample_mesh(cube.with_vertices(np.zeros((8, 3))), 10)) == 0  # no area


def test_normalisation_of_the_ground_truth_moves_the_prediction_too():
    cube = cube_quads(4.0)  # [0, 4]^3
    centre, scale = normalisation(cube)
    assert scale == pytest.approx(2.0) and np.allclose(centre, 2.0)
    moved = apply_normalisation(cube.with_vertices(cube.vertices + 0.4), centre, scale)
    assert np.allclose(moved.vertices.min(axis=0), -0.8)
