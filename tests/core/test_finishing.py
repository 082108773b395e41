"""With normals, the geometry stage keeps whichever fit (with them or without) is better."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere
from spacemesh.geometry import GeometryOptions, fit_report, refine_geometry
from spacemesh.geometry.finishing import finish_geometry, outward
from spacemesh.primitives import sample_surface
from tests.validity import assert_valid_mesh


@pytest.mark.parametrize("flip", [False, True])
def test_the_better_fit_of_with_and_without_normals_is_kept(flip):
    points, normals = sample_surface(cube_quads(1.6), 2000, np.random.default_rng(0))
    points, normals = points.astype(np.float64), normals.astype(np.float64)
    if flip:  # normals that carry nothing but noise: the stage must not use them blindly
        normals = np.random.default_rng(1).normal(size=normals.shape)
    start = icosphere(2)
    options = GeometryOptions()
    mesh, stats = finish_geometry(start, points, normals, options)
    assert_valid_mesh(mesh)
    scores = {}
    for used, given in ((True, normals), (False, None)):
        alone = outward(refine_geometry(start, points, given, options).mesh)
        scores[used] = fit_report(alone, points).score
    assert fit_report(mesh, points).score == pytest.approx(min(scores.values()))
    assert stats["normals_used"] == (scores[True] < scores[False])
    assert stats["n_fragments_dropped"] == 0


def test_without_normals_the_stage_runs_once_and_says_nothing_of_them():
    points, _ = sample_surface(icosphere(3), 1000, np.random.default_rng(0))
    mesh, stats = finish_geometry(icosphere(1), points.astype(np.float64), None,
                                  GeometryOptions())
    assert_valid_mesh(mesh)
    assert "normals_used" not in stats


@pytest.mark.parametrize("dense_flips, target, flipped", [
    (False, 200, False), (True, 200, True),
    (False, 500, True),  # near the count (under 1.5 times it): the dense fit flips
])
def test_a_dense_decode_is_fitted_without_flips_then_collapsed_then_fitted(
        dense_flips, target, flipped):
    from dataclasses import replace

    from spacemesh.geometry.simplify import simplify

    points, _ = sample_surface(cube_quads(1.6), 2000, np.random.default_rng(0))
    points = points.astype(np.float64)
    dense = icosphere(3)  # 642 vertices: a dense decode of a box
    options = GeometryOptions(dense_factor=2.0, dense_flips=dense_flips)
    mesh, _ = finish_geometry(dense, points, None, options, target_vertices=target)
    assert_valid_mesh(mesh)
    assert mesh.n_vertices == target
    # the same three steps by hand: the first fit flips only with dense_flips, or when
    # the decode has under 1.5 times the count
    fitted = refine_geometry(dense, points, None, replace(options, flips=flipped))
    assert (fitted.stats["n_flipped"] > 0) == flipped
    reduced = simplify(fitted.mesh, points, None, target_vertices=target).mesh
    expected = outward(refine_geometry(reduced, points, None, options,
                                       target_vertices=target).mesh)
    assert np.array_equal(mesh.vertices, expected.vertices)
    assert np.array_equal(mesh.face_indices, expected.face_indices)
