"""Crossing diagonals: candidate edges that cross each other on the surface.

Two edges of a mesh never cross. A threshold on embedding distances can still propose
both diagonals of a quad ``a-b-c-d`` (the four sides and both ``a-c`` and ``b-d``: a
4-clique of the candidate graph): one is the mesh's edge, the other joins two vertices
of the next ring, which is the commonest false positive of a trained network. The two
diagonals of a nearly flat quad pass through each other, while the other pairings of a
4-clique's opposite edges (for example a degree-3 vertex's spoke and the opposite side of
its fan) do not. :func:`uncrossed` keeps, of every pair that crosses, the stronger edge
(the smaller embedding distance), weakest pairs first.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Two segments cross when their closest points are inside both and closer than this
#: fraction of the geometric mean of their lengths.
CROSSING_GAP = 0.2


def quad_diagonal_pairs(edges: IntArray, n_vertices: int) -> IntArray:
    """Pairs of candidate edges that are the two diagonals of a candidate quad.

    Parameters
    ----------
    edges : (E, 2) int
        Undirected edges, each once.
    n_vertices : int

    Returns
    -------
    (P, 2) int64
        Indices into ``edges`` of ``a-c`` and ``b-d`` (first index smaller) such that
        ``a-b``, ``b-c``, ``c-d`` and ``d-a`` are edges too.
    """
    neighbours: list[set[int]] = [set() for _ in range(n_vertices)]
    index: dict[tuple[int, int], int] = {}
    for e, (a, b) in enumerate(edges.tolist()):
        neighbours[a].add(b)
        neighbours[b].add(a)
        index[(min(a, b), max(a, b))] = e
    pairs: list[tuple[int, int]] = []
    for e, (a, c) in enumerate(edges.tolist()):
        common = neighbours[a] & neighbours[c]
        if len(common) < 2:
            continue
        for b, d in combinations(sorted(common), 2):
            other = index.get((b, d))
            if other is not None and e < other:
                pairs.append((e, other))
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


def segments_cross(
    positions: FloatArray, first: IntArray, second: IntArray, max_gap: float = CROSSING_GAP
) -> BoolArray:
    """Whether segments cross: closest points inside both, gap below ``max_gap``.

    Parameters
    ----------
    positions : (N, 3) float
    first, second : (P, 2) int
        Segment end points.
    max_gap : float
        The largest gap between the closest points, relative to the geometric mean of
        the two lengths.

    Returns
    -------
    (P,) bool
    """
    p, q = positions[first[:, 0]], positions[first[:, 1]]  # (P, 3)
    r, s = positions[second[:, 0]], positions[second[:, 1]]
    u, v, w = q - p, s - r, p - r
    uu, uv, vv = (u * u).sum(1), (u * v).sum(1), (v * v).sum(1)
    uw, vw = (u * w).sum(1), (v * w).sum(1)
    det = uu * vv - uv * uv  # 0 for parallel segments
    scale = np.sqrt(np.sqrt(uu * vv))
    ok = det > 1e-12 * (uu * vv + 1e-300)
    det = np.where(ok, det, 1.0)
    t_first = (uv * vw - vv * uw) / det
    t_second = (uu * vw - uv * uw) / det
    inside = (t_first > 0) & (t_first < 1) & (t_second > 0) & (t_second < 1)
    gap = np.linalg.norm(w + t_first[:, None] * u - t_second[:, None] * v, axis=1)
    return ok & inside & (gap < max_gap * np.maximum(scale, 1e-300))


def uncrossed(
    positions: FloatArray, edges: IntArray, weakness: FloatArray,
    max_gap: float = CROSSING_GAP,
) -> BoolArray:
    """Which candidate edges to keep so that no two quad diagonals cross.

    Parameters
    ----------
    positions : (N, 3) float
    edges : (E, 2) int
    weakness : (E,) float
        Embedding distance of each edge (larger is weaker).
    max_gap : float
        See :func:`segments_cross`.

    Returns
    -------
    (E,) bool
        False for the weaker edge of each crossing pair, pairs taken weakest first and
        skipped once either edge is gone.
    """
    keep = np.ones(len(edges), dtype=bool)
    pairs = quad_diagonal_pairs(edges, len(positions))
    if pairs.size == 0:
        return keep
    pairs = pairs[segments_cross(positions, edges[pairs[:, 0]], edges[pairs[:, 1]], max_gap)]
    weaker = np.where(weakness[pairs[:, 0]] >= weakness[pairs[:, 1]], pairs[:, 0], pairs[:, 1])
    order = np.argsort(-weakness[weaker], kind="stable")  # weakest pairs first
    for (first, second), drop in zip(pairs[order].tolist(), weaker[order].tolist(), strict=True):
        if keep[first] and keep[second]:
            keep[drop] = False
    return keep
