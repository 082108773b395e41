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
