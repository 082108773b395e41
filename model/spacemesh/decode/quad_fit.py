"""How well the two diagonals of a quad fit a point cloud.

The decode's refinement (:mod:`spacemesh.decode.refinement`) uses these to choose, for two
triangles sharing an edge, the diagonal whose surface passes closer to the conditioning
points: a data-dependent triangulation (Dyn, Levin and Rippa, 1990). Numpy and scipy
only, so the service (no trimesh) runs it.
"""

from __future__ import annotations

import numpy as np

from spacemesh.primitives.closest import nearest_triangles, squared_distances
from spacemesh.typed import FloatArray, IntArray


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
    # numpy types bincount as intp: float64 here with weights, and intp is int64
    return errors[0], errors[1], np.bincount(quad, minlength=len(pairs))  # type: ignore[return-value]


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
