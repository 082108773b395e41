"""Vertices chosen on the input: farthest-point sampling of the conditioning cloud.

The ``start=points`` vertex start (and the vertex budget) pick their vertices here:
farthest-point sampling spreads ``count`` vertices evenly over the cloud, so every part
of the shape gets vertices, thin parts included. The first vertex is drawn with the
request's seed, so the seed changes the result even when nothing is denoised.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray, IntArray


def farthest_point_sampling(points: FloatArray, count: int, *, seed: int = 0) -> IntArray:
    """Indices of ``count`` points, each the farthest from those chosen before it.

    Parameters
    ----------
    points : (P, 3) float
        Finite points.
    count : int
        How many to choose (at most ``P``; fewer are returned for a smaller cloud).
    seed : int
        Draws the first point.

    Returns
    -------
    (min(count, P),) int64
        Distinct indices, in the order they were chosen.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    count = int(min(max(count, 0), len(points)))
    chosen = np.empty(count, dtype=np.int64)
    if count == 0:
        return chosen
    chosen[0] = np.random.default_rng(int(seed)).integers(len(points))
    nearest = np.full(len(points), np.inf)  # (P,) squared distance to the chosen set
    for i in range(1, count):
        gap = points - points[chosen[i - 1]]
        np.minimum(nearest, np.einsum("pd,pd->p", gap, gap), out=nearest)
        chosen[i] = int(np.argmax(nearest))
    return chosen
