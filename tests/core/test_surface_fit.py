"""How triangles fit a point cloud (:mod:`spacemesh.primitives.closest`,
:mod:`spacemesh.decode.quad_fit`): closest points,
nearest triangles and the quad errors the decode's fit flips read."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.decode.quad_fit import QuadFit, quad_fit_errors
from spacemesh.examples import icosphere
from spacemesh.primitives import sample_surface
from spacemesh.primitives.closest import (
    closest_points_on_triangles,
    nearest_points,
    nearest_triangles,
    squared_distances,
)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = np.clip((p - a) @ ab / max(ab @ ab, 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(a + t * ab - p))


def test_closest_points_match_trimesh_and_lie_on_the_triangles():
    trimesh = pytest.importorskip("trimesh", reason="trimesh is the reference")
    rng = np.random.default_rng(0)
    corners = rng.normal(size=(5000, 3, 3))
    points = 2.0 * rng.normal(size=(5000, 3))
    ours = closest_points_on_triangles(points, corners)
    theirs = trimesh.triangles.closest_point(corners, points)
    np.testing.assert_allclose(np.linalg.norm(ours - points, axis=1),
                               np.linalg.norm(theirs - points, axis=1), atol=1e-9)
    # on the triangle: barycentric coordinates in [0, 1]
    bary = trimesh.triangles.points_to_barycentric(corners, ours)
    assert bary.min() > -1e-9 and bary.max() < 1 + 1e-9
    # every region of the test is reached (corners, sides, inside)
    assert np.isclose(ours[:, None], corners).all(axis=2).any(axis=1).sum() > 100
    assert (bary.min(axis=1) > 1e-6).sum() > 100


def test_degenerate_triangles_give_the_closest_point_of_their_sides():
    rng = np.random.default_rng(1)
    corners = rng.normal(size=(60, 3, 3))
    corners[:20, 2] = corners[:20, 1]  # c == b
    corners[20:40, 1] = corners[20:40, 0]  # b == a
    corners[40:50, 2] = 0.5 * (corners[40:50, 0] + corners[40:50, 1])  # collinear
    corners[50:] = corners[50:, :1]  # a point
    points = 2.0 * rng.normal(size=(60, 3))
    got = np.sqrt(squared_distances(points, corners))
    want = [min(_segment_distance(p, t[i], t[(i + 1) % 3]) for i in range(3))
            for p, t in zip(points, corners, strict=True)]
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert np.isfinite(closest_points_on_triangles(points, corners)).all()


def _sphere_points(subdivisions: int = 2, count: int = 1500):
    sphere = icosphere(subdivisions)
    points, _ = sample_surface(sphere, count, np.random.default_rng(2))
    return sphere, points.astype(np.float64)


def _brute_force_distances(points, positions, triangles):
    n, t = len(points), len(triangles)
    gap = squared_distances(np.repeat(points, t, axis=0),
                            np.tile(positions[triangles], (n, 1, 1)))
    return gap.reshape(n, t)


def test_nearest_triangles_are_the_nearest():
    sphere, points = _sphere_points()
    faces = np.asarray(sphere.faces, dtype=np.int64)
    points = points + 0.02 * np.random.default_rng(3).normal(size=points.shape)
    owner, gap = nearest_triangles(points, sphere.vertices, faces)
    every = _brute_force_distances(points, sphere.vertices, faces)
    np.testing.assert_allclose(every[np.arange(len(points)), owner], every.min(axis=1),
                               atol=1e-12)
    np.testing.assert_allclose(gap, every.min(axis=1), atol=1e-12)


def test_nearest_points_are_the_closest_points_of_the_nearest_triangles():
    sphere, points = _sphere_points()
    faces = np.asarray(sphere.faces, dtype=np.int64)
    points = points + 0.02 * np.random.default_rng(4).normal(size=points.shape)
    owner, gap, closest = nearest_points(points, sphere.vertices, faces)
    expected_owner, expected_gap = nearest_triangles(points, sphere.vertices, faces)
    np.testing.assert_array_equal(owner, expected_owner)
    np.testing.assert_array_equal(gap, expected_gap)
    # the very point each distance was measured to, bit for bit
    np.testing.assert_array_equal(
        closest, closest_points_on_triangles(points, sphere.vertices[faces[owner]]))
    np.testing.assert_allclose(np.sum((closest - points) ** 2, axis=1), gap, atol=1e-15)


def _quad(faces: np.ndarray):
    """Two faces sharing an edge: their rows and ``a, b, c, d`` (``t1 = (a, b, c)``,
    ``t2 = (b, a, d)``)."""
    t1 = 0
    a, b, c = faces[t1].tolist()
    t2 = next(i for i, f in enumerate(faces.tolist())
              if i != t1 and any((f[k], f[(k + 1) % 3]) == (b, a) for k in range(3)))
    (d,) = set(faces[t2].tolist()) - {a, b}
    return t1, t2, (a, b, c, d)


def test_quad_errors_are_zero_on_the_true_diagonal_and_positive_on_the_other():
    sphere, points = _sphere_points()
    faces = np.asarray(sphere.faces, dtype=np.int64)
    owner, _ = nearest_triangles(points, sphere.vertices, faces)
    t1, t2, (a, b, c, d) = _quad(faces)
    current = np.array([[[a, b, c], [b, a, d]]])
    flipped = np.array([[[d, b, c], [c, a, d]]])
    before, after, count = quad_fit_errors(points, owner, sphere.vertices,
                                           np.array([[t1, t2]]), (current, flipped))
    assert count[0] == np.isin(owner, [t1, t2]).sum() > 0
    assert before[0] < 1e-12 < after[0]  # points on the true triangles (float32 rounding)
    mine = np.isin(owner, [t1, t2])
    direct = np.minimum(*(squared_distances(points[mine], np.repeat(
        sphere.vertices[[tri]], mine.sum(), axis=0)) for tri in flipped[0]))
    assert after[0] == pytest.approx(direct.sum())


def test_quad_fit_follows_a_flip():
    sphere, points = _sphere_points()
    faces = np.asarray(sphere.faces, dtype=np.int64).copy()
    fit = QuadFit(points, sphere.vertices, faces)
    t1, t2, (a, b, c, d) = _quad(faces)
    pairs, corners = np.array([[t1, t2]]), np.array([[a, b, c, d]])
    before, after = fit.errors(pairs, corners)
    faces[t1], faces[t2] = (d, b, c), (c, a, d)
    fit.flipped(pairs)
    moved = np.isin(fit.owner, pairs)
    every = _brute_force_distances(points, sphere.vertices, faces)
    # the points of the two triangles found their nearest triangle again
    np.testing.assert_allclose(every[np.arange(len(points)), fit.owner][moved],
                               every.min(axis=1)[moved], atol=1e-12)
    # flipping back is measured afresh (the quad's triangles changed): the same errors
    back_before, back_after = fit.errors(pairs, np.array([[c, d, b, a]]))
    assert back_before[0] == pytest.approx(after[0], rel=1e-9, abs=1e-15)
    assert back_after[0] == pytest.approx(before[0], abs=1e-15)
