"""How well triangles fit a point cloud: closest points, nearest triangles, quad errors.

The decode's refinement (:mod:`spacemesh.geometry.refinement`) uses these to choose, for two
triangles sharing an edge, the diagonal whose surface passes closer to the conditioning
points: a data-dependent triangulation (Dyn, Levin and Rippa, 1990). Numpy and scipy
only, so the service (no trimesh) runs it.
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


def nearest_triangles(points: FloatArray, positions: FloatArray, triangles: IntArray
                      ) -> tuple[IntArray, FloatArray]:
    """The triangle nearest to each point, measured exactly among the triangles of its
    :data:`NEAREST_SAMPLES` nearest surface samples (the centroids of a
    :data:`SAMPLE_LEVEL` subdivision of every triangle).

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
    """
    corners = positions[triangles]  # (T, 3, 3)
    weights = _subtriangle_centroids(SAMPLE_LEVEL)  # (S, 3)
    samples = np.einsum("sk,tkd->tsd", weights, corners).reshape(-1, 3)  # (T S, 3)
    k = min(NEAREST_SAMPLES, len(samples))
    _, near = cKDTree(samples).query(points, k=k)
    near = np.asarray(near, dtype=np.int64).reshape(len(points), k) // len(weights)  # (P, k)
    gap = squared_distances(np.repeat(points, k, axis=0), corners[near.reshape(-1)])
    best = np.argmin(gap.reshape(-1, k), axis=1)
    rows = np.arange(len(points))
    return near[rows, best], gap.reshape(-1, k)[rows, best]


def quad_fit_errors(
    points: FloatArray, owner: IntArray, positions: FloatArray, pairs: IntArray,
    options: tuple[IntArray, IntArray],
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Squared-distance error of the points of two triangles under two triangulations.

    Parameters
    ----------
    points : (P, 3) float
    owner : (P,) int
        Each point's triangle (:func:`nearest_triangles`).
    positions : (N, 3) float
    pairs : (Q, 2) int
        The two triangles of each quad, whose points are measured.
    options : tuple of two (Q, 2, 3) int
        Each quad's current and alternative triangles (vertex indices).

    Returns
    -------
    current, alternative : (Q,) float
        Sum over the points of the quad of the squared distance to the nearer of the
        option's two triangles.
    count : (Q,) int
        Points measured per quad.
    """
    n_tri = int(max(owner.max(initial=-1), pairs.max(initial=-1))) + 1
    order = np.argsort(owner, kind="stable")
    per_tri = np.bincount(owner, minlength=n_tri)
    start = np.concatenate([[0], np.cumsum(per_tri)[:-1]])
    quads, members = [], []
    for side in range(2):
        t = pairs[:, side]
        counts = per_tri[t]
        quad = np.repeat(np.arange(len(pairs)), counts)
        first = np.repeat(np.cumsum(counts) - counts, counts)
        members.append(order[np.repeat(start[t], counts) + np.arange(len(quad)) - first])
        quads.append(quad)
    quad, member = np.concatenate(quads), np.concatenate(members)
    p = points[member]
    errors = []
    for tris in options:
        near = np.minimum(squared_distances(p, positions[tris[quad, 0]]),
                          squared_distances(p, positions[tris[quad, 1]]))
        errors.append(np.bincount(quad, weights=near, minlength=len(pairs)))
    return errors[0], errors[1], np.bincount(quad, minlength=len(pairs))


class QuadFit:
    """The points of a triangulation and what flipping its quads does to their fit.

    Each point belongs to its nearest triangle (:func:`nearest_triangles`). A flip
    replaces two triangles by two over the same quad, so :meth:`flipped` only looks
    again for the nearest triangles of the points the two had, and the errors of every
    quad whose triangles kept their points stay valid: :meth:`errors` caches them by
    the quad's triangles, corners and the triangles' point-set versions.

    Parameters
    ----------
    points : (P, 3) float
        Non-finite rows are left out.
    positions : (N, 3) float
        Finite at the corners of ``triangles``.
    triangles : (T, 3) int
        Rows are updated in place by the caller; :meth:`flipped` is told which.
    """

    def __init__(self, points: FloatArray, positions: FloatArray, triangles: IntArray):
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self.points = points[np.isfinite(points).all(axis=1)]  # (P, 3)
        self.positions = positions
        self.triangles = triangles
        self.owner, residual = nearest_triangles(self.points, positions, triangles)  # (P,)
        self._version = np.zeros(len(triangles), dtype=np.int64)
        #: The median squared distance of the points to the triangulation: their noise.
        self.noise = float(np.median(residual)) if len(residual) else 0.0
        self._cache: dict[tuple[int, ...], tuple[float, float]] = {}

    def errors(self, pairs: IntArray, corners: IntArray) -> tuple[FloatArray, FloatArray]:
        """Fit errors of quads before and after their flip (:func:`quad_fit_errors`).

        Parameters
        ----------
        pairs : (Q, 2) int
            Triangles ``t1, t2`` of each quad.
        corners : (Q, 4) int
            ``a, b, c, d``: ``t1`` is ``(a, b, c)``, ``t2`` is ``(b, a, d)``; the flip
            makes ``(d, b, c)`` and ``(c, a, d)``.

        Returns
        -------
        before, after : (Q,) float
        """
        stamp = np.concatenate([pairs, corners, self._version[pairs]], axis=1)  # (Q, 8)
        keys = [tuple(row) for row in stamp.tolist()]
        missing = [i for i, key in enumerate(keys) if key not in self._cache]
        if missing:
            m = np.asarray(missing)
            a, b, c, d = corners[m].T
            current = np.stack([np.stack([a, b, c], 1), np.stack([b, a, d], 1)], axis=1)
            flipped = np.stack([np.stack([d, b, c], 1), np.stack([c, a, d], 1)], axis=1)
            before, after, _ = quad_fit_errors(self.points, self.owner, self.positions,
                                               pairs[m], (current, flipped))
            for i, e0, e1 in zip(missing, before.tolist(), after.tolist(), strict=True):
                self._cache[keys[i]] = (e0, e1)
        values = np.asarray([self._cache[key] for key in keys], dtype=np.float64)
        return values[:, 0], values[:, 1]

    def flipped(self, pairs: IntArray) -> None:
        """Re-assign the points of flipped quads (rows of :attr:`triangles` already
        hold the new triangles).

        Parameters
        ----------
        pairs : (F, 2) int
            The two triangle rows of each flipped quad.
        """
        if not len(pairs):
            return
        moved = np.flatnonzero(np.isin(self.owner, pairs))
        if not len(moved):
            return
        new, _ = nearest_triangles(self.points[moved], self.positions, self.triangles)
        self._version[np.union1d(self.owner[moved], new)] += 1
        self.owner[moved] = new
