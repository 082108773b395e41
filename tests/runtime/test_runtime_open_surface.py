"""An open surface through the whole pipeline, with the shipped model: of its two
candidates (the chosen seed's mesh fitted then trimmed, and its decode trimmed then
fitted), the one kept does not cross where the other does not, and fits at least as
well; a closed surface never makes the second."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import icosphere
from spacemesh.primitives import sample_surface
from spacemesh.runtime import MeshGenerator
from spacemesh.runtime.choice import crosses
from tests.validity import assert_valid_mesh


@pytest.fixture(scope="module")
def generator(shipped):
    return MeshGenerator.from_repository(None, threads=1)


@pytest.fixture(scope="module")
def bumpy_sphere():
    """Points on a bumpy sphere (a shape with detail), with their normals."""
    sphere = icosphere(4)
    v = sphere.vertices
    bumps = 1.0 + 0.08 * np.sin(4 * v[:, 0]) * np.cos(3 * v[:, 1])
    points, normals = sample_surface(sphere.with_vertices(v * bumps[:, None]), 2048,
                                     np.random.default_rng(0))
    return points.astype(np.float64), normals.astype(np.float64)


@pytest.mark.parametrize("direction", [[0, 0, 1], [1, 0, 0]])
def test_a_one_sided_scan_keeps_the_better_of_its_two_candidates(generator, bumpy_sphere,
                                                                  direction, monkeypatch):
    import spacemesh.runtime.pipeline as pipeline

    points, normals = bumpy_sphere
    seen = points[normals @ np.asarray(direction, dtype=np.float64) > 0]
    result = generator.generate(seen, seed=0)
    assert result.fit is not None and result.fit.open_surface
    assert_valid_mesh(result.mesh, open_surface=True)
    assert result.decoded is None  # the decode is freed once used
    # each candidate alone: the second always kept, then none made
    with monkeypatch.context() as patch:
        patch.setattr(pipeline, "_rank",
                      lambda r: (not r.geometry_stats.get("surface_trimmed_first"), 0.0))
        second = generator.generate(seen, seed=0)
    assert second.geometry_stats["surface_trimmed_first"]
    assert_valid_mesh(second.mesh, open_surface=True)
    monkeypatch.setattr(MeshGenerator, "_trimmed_first", lambda self, chosen, *args: chosen)
    first = generator.generate(seen, seed=0)
    assert first.fit is not None and "surface_trimmed_first" not in first.geometry_stats
    assert second.fit is not None
    better = min((first, second), key=lambda r: (crosses(r), r.fit.score))
    np.testing.assert_array_equal(result.mesh.vertices, better.mesh.vertices)
    assert result.geometry_stats["surface_trimmed_first"] is (better is second)


def test_a_complete_cloud_makes_no_second_candidate(generator, bumpy_sphere):
    points, _ = bumpy_sphere
    result = generator.generate(points, seed=0)
    assert result.fit is not None and not result.fit.open_surface
    assert "surface_trimmed_first" not in result.geometry_stats
    assert result.decoded is None


def test_a_flat_sheet_comes_back_whole_from_its_slab(generator, monkeypatch):
    """375 points on a 2 x 2 square: decoded on its own, the sheet's two coincident
    layers cross and come back in pieces; the slab behind it gives one piece that covers
    the points (geometry/sheet.py), and it is kept as the better candidate."""
    rng = np.random.default_rng(1)
    sheet = np.c_[rng.uniform(-1, 1, (375, 2)), np.zeros(375)]  # (375, 3)
    result = generator.generate(sheet, seed=0)
    assert result.fit is not None and result.fit.open_surface
    assert_valid_mesh(result.mesh, open_surface=True)
    assert result.geometry_stats["surface_slab"] is True
    assert result.fit.pieces == 1 and result.fit.coverage > 0.95
    depth = np.abs(result.mesh.vertices[:, 2])  # (V,) on the sheet, not on its copy
    assert np.quantile(depth, 0.95) < 0.01 and depth.max() < 0.05 * np.sqrt(8)
    monkeypatch.setattr(MeshGenerator, "_flat_slab", lambda self, chosen, *args: chosen)
    alone = generator.generate(sheet, seed=0)
    assert alone.fit is not None and alone.fit.score > result.fit.score
    assert alone.fit.pieces > 1 or alone.fit.coverage < 0.9


def test_a_curved_scan_makes_no_slab(generator, bumpy_sphere):
    points, normals = bumpy_sphere
    seen = points[normals[:, 2] > 0]
    result = generator.generate(seen, seed=0)
    assert result.fit is not None and result.fit.open_surface
    assert "surface_slab" not in result.geometry_stats


def test_a_large_sheet_gives_its_slab_the_fit_subset(generator, monkeypatch):
    """The slab of a sheet of 12,000 points is made from the fixed subset of 4,096 the
    fit uses, so its request stays small whatever the upload."""
    import spacemesh.runtime.pipeline as pipeline
    from spacemesh.runtime.request import MAX_FIT_POINTS

    made = []
    real = pipeline.slab_points

    def spy(points, facing):
        made.append(len(points))
        return real(points, facing)

    monkeypatch.setattr(pipeline, "slab_points", spy)
    rng = np.random.default_rng(2)
    sheet = np.c_[rng.uniform(-1, 1, (12_000, 2)), np.zeros(12_000)]
    result = generator.generate(sheet, seed=0)
    assert made == [MAX_FIT_POINTS]
    assert result.fit is not None and result.fit.open_surface
    assert "surface_slab" in result.geometry_stats
    assert_valid_mesh(result.mesh, open_surface=True)
