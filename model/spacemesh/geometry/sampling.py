"""Vertices chosen on the input: farthest-point sampling of the conditioning cloud.

The ``start=points`` vertex start (and the vertex budget) pick their vertices here:
farthest-point sampling spreads ``count`` vertices evenly over the cloud, so every part
of the shape gets vertices, thin parts included. The first vertex is drawn with the
request's seed, so the seed changes the result even when nothing is denoised.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray, IntArray

#: Neighbours compared by :func:`feature_weights`.
FEATURE_NEIGHBOURS = 10
#: A point is on a sharp feature when a neighbour's normal is this far from its own
#: (``|n_i . n_j|`` below it: about 60 degrees or more).
FEATURE_DOT = 0.5


def farthest_point_sampling(points: FloatArray, count: int, *, seed: int = 0,
                            weights: FloatArray | None = None) -> IntArray:
    """Indices of ``count`` points, each the farthest from those chosen before it.

    Parameters
    ----------
    points : (P, 3) float
        Finite points.
    count : int
        How many to choose (at most ``P``; fewer are returned for a smaller cloud).
    seed : int
        Draws the first point.
    weights : (P,) float, optional
        Distances are multiplied by these (a point of weight 2 is chosen as if it were
        twice as far): regions of larger weight get denser vertices.

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
    scale = np.ones(len(points)) if weights is None else np.asarray(weights, np.float64) ** 2
    chosen[0] = np.random.default_rng(int(seed)).integers(len(points))
    nearest = np.full(len(points), np.inf)  # (P,) weighted squared distance to the chosen
    for i in range(1, count):
        gap = points - points[chosen[i - 1]]
        np.minimum(nearest, np.einsum("pd,pd->p", gap, gap) * scale, out=nearest)
        nearest[chosen[i - 1]] = -1.0  # never again
        chosen[i] = int(np.argmax(nearest))
    return chosen


def feature_weights(points: FloatArray, boost: float, *, k: int = FEATURE_NEIGHBOURS
                    ) -> FloatArray:
    """FPS weights that favour sharp features: ``1 + boost`` at points whose
    neighbourhood's plane fits disagree (the smallest ``|n_i . n_j|`` over the ``k``
    nearest neighbours below :data:`FEATURE_DOT`, as the ECD metric finds edges), 1
    elsewhere.

    Parameters
    ----------
    points : (P, 3) float
    boost : float
    k : int

    Returns
    -------
    (P,) float64
    """
    from scipy.spatial import cKDTree

    from spacemesh.geometry.fitting import estimate_point_normals

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    weights = np.ones(len(points))
    k = int(min(k, len(points)))
    if boost <= 0 or k < 4:
        return weights
    normals = estimate_point_normals(points)
    _, near = cKDTree(points).query(points, k=k)
    dots = np.abs(np.einsum("pd,pkd->pk", normals, normals[near]))  # (P, k)
    weights[dots.min(axis=1) < FEATURE_DOT] += boost
    return weights
