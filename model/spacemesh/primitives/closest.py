"""Closest points on triangles and the nearest triangle of each point (numpy and scipy).

The queries behind every point-to-surface distance: the vertex fit, the fit report, the
decode's diagonal choice (:mod:`spacemesh.decode.quad_fit`) and hole filling.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.typed import FloatArray, IntArray

#: Every triangle is sampled at the centroids of its subdivision into this squared.
SAMPLE_LEVEL = 4
#: The triangles of this many nearest samples are measured exactly.
NEAREST_SAMPLES = 8
#: Triangles with ``|ab x ac|^2`` below this times ``max(|ab|, |ac|)^4`` are degenerate.
DEGENERATE = 1e-12


def _dot(u: FloatArray, v: FloatArray) -> FloatArray:
    return np.einsum("mk,mk->m", u, v)


def closest_points_on_triangles(points: FloatArray, corners: FloatArray) -> FloatArray:
    """The point of each triangle closest to each point, pairwise.

    The region test of Ericson, *Real-Time Collision Detection* (2005), Sec. 5.1.5,
    vectorised. A degenerate triangle (zero area) gives the closest point of its sides.

    Parameters
    ----------
    points : (M, 3) float
    corners : (M, 3, 3) float
        Triangle ``m`` is ``corners[m]``.

    Returns
    -------
    (M, 3) float
    """
    p = np.asarray(points, dtype=np.float64)
    a, b, c = (np.asarray(corners[:, i], dtype=np.float64) for i in range(3))
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(invalid="ignore", divide="ignore"):
        denom = va + vb + vc
        out = a + ab * (vb / denom)[:, None] + ac * (vc / denom)[:, None]  # inside
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        t_ac = d2 / (d2 - d6)
        t_ab = d1 / (d1 - d3)
    # Ericson returns at the first region that matches: apply them last to first
    regions = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t_bc[:, None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None]),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for mask, value in regions:
        out = np.where(mask[:, None], value, out)
    normal = np.cross(ab, ac)
    scale = np.maximum(_dot(ab, ab), _dot(ac, ac))
    flat = (_dot(normal, normal) <= DEGENERATE * scale * scale) | ~np.isfinite(out).all(axis=1)
    if flat.any():
        out[flat] = _closest_on_sides(p[flat], a[flat], b[flat], c[flat])
    return out


def _closest_on_segments(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    ab = b - a
    length = _dot(ab, ab)
    t = np.clip(_dot(p - a, ab) / np.where(length > 0, length, 1.0), 0.0, 1.0)
    return a + ab * t[:, None]


def _closest_on_sides(p: FloatArray, a: FloatArray, b: FloatArray, c: FloatArray
                      ) -> FloatArray:
    """Closest points on the three sides of (degenerate) triangles."""
    near = np.stack([_closest_on_segments(p, u, v) for u, v in ((a, b), (b, c), (c, a))],
                    axis=1)  # (K, 3, 3)
    gap = np.linalg.norm(near - p[:, None], axis=2)
    return near[np.arange(len(p)), np.argmin(gap, axis=1)]


def squared_distances(points: FloatArray, corners: FloatArray) -> FloatArray:
    """Squared distance from each point to its triangle, pairwise.

    Parameters
    ----------
    points : (M, 3) float
    corners : (M, 3, 3) float

    Returns
    -------
    (M,) float
    """
    gap = closest_points_on_triangles(points, corners) - points
    return _dot(gap, gap)


def _subtriangle_centroids(level: int) -> FloatArray:
    """Barycentric coordinates ``(level^2, 3)`` of the centroids of the ``level^2``
    triangles of a regular subdivision of a triangle."""
    rows = []
    for i in range(level):
        for j in range(level - i):
            rows.append((i + 1 / 3, j + 1 / 3))  # upward sub-triangle
            if j < level - i - 1:
                rows.append((i + 2 / 3, j + 2 / 3))  # downward
    uv = np.asarray(rows) / level
    return np.column_stack([1.0 - uv.sum(axis=1), uv])


def mean_spacing(points: FloatArray) -> float:
    """The mean distance from each point to its nearest other point.

    Parameters
    ----------
    points : (P, 3) float
        At least two.

    Returns
    -------
    float
    """
    distances, _ = cKDTree(points).query(points, k=2)  # (P, 2): self, nearest other
    return float(np.mean(distances[:, 1]))


def _candidates(points: FloatArray, positions: FloatArray, triangles: IntArray, k: int
                ) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    """The triangles of each point's ``k`` nearest surface samples (the rows ``near``
    ``(P, k)``), each (point, triangle) pair measured once: ``inverse`` (``(P k,)``, into
    the pairs), their closest points ``(U, 3)`` and squared distances ``(U,)``."""
    corners = positions[triangles]  # (T, 3, 3)
    weights = _subtriangle_centroids(SAMPLE_LEVEL)  # (S, 3)
    samples = np.einsum("sk,tkd->tsd", weights, corners).reshape(-1, 3)  # (T S, 3)
    k = min(k, len(samples))
    # built unbalanced (sliding midpoint): a quarter faster to build and query here, and
    # the same neighbours (only exact ties could come back in another order)
    _, near = cKDTree(samples, balanced_tree=False).query(points, k=k)
    near = np.asarray(near, dtype=np.int64).reshape(len(points), k) // len(weights)  # (P, k)
    # a triangle's samples lie together: measure each (point, triangle) pair once
    keys = np.arange(len(points))[:, None] * len(triangles) + near  # (P, k)
    unique, inverse = np.unique(keys, return_inverse=True)
    measured = np.asarray(points)[unique // len(triangles)]  # (U, 3)
    closest = closest_points_on_triangles(measured, corners[unique % len(triangles)])
    offset = closest - measured
    return near, inverse.reshape(-1), closest, _dot(offset, offset)


def candidate_triangles(points: FloatArray, positions: FloatArray, triangles: IntArray,
                        k: int = NEAREST_SAMPLES) -> tuple[IntArray, FloatArray]:
    """The triangles of each point's ``k`` nearest surface samples (the centroids of a
    :data:`SAMPLE_LEVEL` subdivision of every triangle), with their exact squared
    distances.

    Parameters
    ----------
    points : (P, 3) float
    positions : (N, 3) float
    triangles : (T, 3) int
    k : int

    Returns
    -------
    near : (P, k) int
        Rows of ``triangles`` (repeats possible); ``k`` at most the samples.
    gap : (P, k) float
        Squared distance from each point to each of them.
    """
    near, inverse, _, gap = _candidates(points, positions, triangles, k)
    return near, gap[inverse].reshape(near.shape)


def nearest_points(points: FloatArray, positions: FloatArray, triangles: IntArray
                   ) -> tuple[IntArray, FloatArray, FloatArray]:
    """The triangle nearest to each point, measured exactly among its
    :func:`candidate_triangles`, and the closest point on it.

    Parameters
    ----------
    points : (P, 3) float
    positions : (N, 3) float
    triangles : (T, 3) int

    Returns
    -------
    owner : (P,) int
        Row of ``triangles``.
    gap : (P,) float
        Squared distance from each point to its triangle.
    closest : (P, 3) float
        The point of ``triangles[owner]`` that distance was measured to.
    """
    near, inverse, closest, gap = _candidates(points, positions, triangles, NEAREST_SAMPLES)
    pair = inverse.reshape(near.shape)  # (P, k) into the measured pairs
    rows = np.arange(len(points))
    choice = np.argmin(gap[pair], axis=1)  # (P,) the first of the nearest
    best = pair[rows, choice]  # (P,)
    return near[rows, choice], gap[best], closest[best]


def nearest_triangles(points: FloatArray, positions: FloatArray, triangles: IntArray
                      ) -> tuple[IntArray, FloatArray]:
    """:func:`nearest_points` without the closest points: ``owner`` ``(P,)`` and ``gap``
    ``(P,)``."""
    owner, gap, _ = nearest_points(points, positions, triangles)
    return owner, gap


def mean_distance(points: FloatArray, positions: FloatArray, triangles: IntArray) -> float:
    """The mean distance from ``points`` to the surface of ``triangles`` (exact, through
    :func:`nearest_triangles`).

    Parameters
    ----------
    points : (P, 3) float
    positions : (N, 3) float
    triangles : (T, 3) int
        At least one.

    Returns
    -------
    float
    """
    _, gap = nearest_triangles(points, positions, triangles)
    return float(np.sqrt(np.maximum(gap, 0.0)).mean())
