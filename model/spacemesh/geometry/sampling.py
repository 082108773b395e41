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
                            weights: FloatArray | None = None, block: int = 256
                            ) -> IntArray:
    """Indices of ``count`` points, each the farthest from those chosen before it.

    Exact and fast on big clouds: the points are grouped into compact blocks
    (:class:`PointBlocks`), and a new choice updates only the blocks it can come closer
    to than their farthest point already is (a bounding-box test with a margin of 1e-9,
    far above rounding); every other block keeps its distances exactly as the plain
    ``O(P count)`` loop would. The distances computed are those of the plain loop, and
    ties go to the lowest index, so the result is the same indices, for any cloud.

    Parameters
    ----------
    points : (P, 3) float
        Finite points.
    count : int
        How many to choose (at most ``P``; fewer are returned for a smaller cloud).
    seed : int
        Draws the first point.
    weights : (P,) float, optional
        Non-negative; distances are multiplied by these (a point of weight 2 is chosen as
        if it were twice as far): regions of larger weight get denser vertices.
    block : int
        Most points of a block (the result does not depend on it).

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
    blocks = PointBlocks.build(points, scale, block)
    for i in range(1, count):
        chosen[i] = blocks.choose(int(chosen[i - 1]))
    return chosen


class PointBlocks:
    """A cloud in compact blocks for :func:`farthest_point_sampling`: each block's
    bounding box, smallest weight and largest weighted squared distance to the chosen.

    Parameters
    ----------
    order : (P,) int64
        The points' indices, block by block.
    points : (P, 3) float64
        ``points[order]``.
    scale : (P,) float64
        Squared weights, in the same order.
    starts : (B + 1,) int64
        Block ``b`` holds rows ``starts[b]:starts[b + 1]``.
    """

    #: A block is skipped only when its bound beats its farthest point by this share.
    MARGIN = 1e-9

    def __init__(self, order: IntArray, points: FloatArray, scale: FloatArray,
                 starts: IntArray) -> None:
        self.order, self.points, self.scale, self.starts = order, points, scale, starts
        self.where = np.empty_like(order)
        self.where[order] = np.arange(len(order))  # row of each point
        self.block = np.repeat(np.arange(len(starts) - 1), np.diff(starts))  # (P,)
        first = starts[:-1]
        self.low = np.minimum.reduceat(points, first, axis=0)  # (B, 3)
        self.high = np.maximum.reduceat(points, first, axis=0)
        self.least = np.minimum.reduceat(scale, first)  # (B,)
        self.nearest = np.full(len(order), np.inf)  # (P,) by row
        self.farthest = np.full(len(first), np.inf)  # (B,) largest of nearest

    @classmethod
    def build(cls, points: FloatArray, scale: FloatArray, size: int) -> PointBlocks:
        """Blocks of at most ``size`` points by median splits along the widest axis.

        Parameters
        ----------
        points : (P, 3) float64
        scale : (P,) float64
        size : int

        Returns
        -------
        PointBlocks
        """
        order, columns = np.arange(len(points)), np.ascontiguousarray(points.T)  # (3, P)
        starts, pending = [], [(0, len(points))]
        while pending:
            lo, hi = pending.pop()
            if hi - lo <= size:
                starts.append(lo)
                continue
            part = columns[:, lo:hi]
            axis = int(np.argmax(part.max(axis=1) - part.min(axis=1)))
            half = (hi - lo) // 2
            split = np.argpartition(part[axis], half)
            columns[:, lo:hi], order[lo:hi] = part[:, split], order[lo:hi][split]
            pending += [(lo, lo + half), (lo + half, hi)]
        bounds = np.array([*sorted(starts), len(points)], dtype=np.int64)
        return cls(order, points[order], scale[order], bounds)

    def choose(self, last: int) -> int:
        """Take point ``last`` as chosen and return the next choice.

        Parameters
        ----------
        last : int
            The point chosen last (an index into the cloud).

        Returns
        -------
        int
            The point farthest from every chosen one (weighted), the lowest index on a tie.
        """
        row = int(self.where[last])
        centre = self.points[row]
        outside = np.maximum(np.maximum(self.low - centre, centre - self.high), 0.0)
        bound = np.einsum("bd,bd->b", outside, outside) * self.least * (1.0 - self.MARGIN)
        touched = bound < self.farthest
        touched[self.block[row]] = True
        blocks = np.flatnonzero(touched)
        first, lengths = self.starts[blocks], np.diff(self.starts)[blocks]
        offsets = np.concatenate(([0], np.cumsum(lengths)[:-1]))
        rows = np.arange(int(lengths.sum())) + np.repeat(first - offsets, lengths)
        gap = self.points[rows] - centre
        near = np.minimum(self.nearest[rows], np.einsum("pd,pd->p", gap, gap)
                          * self.scale[rows])
        near[rows == row] = -1.0  # never again
        self.nearest[rows] = near
        self.farthest[blocks] = np.maximum.reduceat(near, offsets)
        top = self.farthest.max()
        best = len(self.order)
        for b in np.flatnonzero(self.farthest == top):
            lo, hi = self.starts[b], self.starts[b + 1]
            ties = lo + np.flatnonzero(self.nearest[lo:hi] == top)
            best = min(best, int(self.order[ties].min()))
        return best


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
