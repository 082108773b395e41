"""The flat fill of a hole: the least-area triangulation of its loops (Liepa 2003,
Sec. 3.1; the fill MeshFix-like tools start from), as triangles over the loops' own
vertices (:func:`flat_surface`) or as the surface a patch's vertices are projected onto
(:func:`flat_positions`).

numpy and scipy only.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives.closest import closest_points_on_triangles
from spacemesh.repair.fill.loops import patch_loops
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Longest loop the least-area triangulation is built for (its dynamic programme takes
#: ``O(n^3)`` work): a longer one has no flat fill (the fairing keeps the membrane); the
#: default of :attr:`spacemesh.repair.fill.policy.FillPolicy.max_flat_loop`.
MAX_FLAT_LOOP = 300
#: Triangles (nearest by centroid) each vertex is projected onto in :func:`flat_positions`.
FLAT_NEIGHBOURS = 8


def min_area_triangles(points: FloatArray) -> IntArray:
    """The triangulation of a closed polygon of least total area (Liepa 2003, Sec. 3.1;
    the fill MeshFix-like tools start from), by dynamic programming over its sub-chains.

    Parameters
    ----------
    points : (n, 3) float
        The polygon's corners in order, ``n >= 3``.

    Returns
    -------
    (n - 2, 3) int64
        Corner indices of each triangle, in the polygon's direction.
    """
    n = len(points)
    p = np.asarray(points, dtype=np.float64)
    cost = np.zeros((n, n))
    best = np.zeros((n, n), dtype=np.int64)
    for length in range(2, n):
        for a in range(n - length):
            b = a + length
            k = np.arange(a + 1, b)
            area = 0.5 * np.linalg.norm(np.cross(p[k] - p[a], p[b] - p[a]), axis=1)
            total = cost[a, k] + cost[k, b] + area
            m = int(np.argmin(total))
            cost[a, b], best[a, b] = total[m], k[m]
    triangles, stack = [], [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a >= 2:
            c = int(best[a, b])
            triangles.append((a, c, b))
            stack += [(a, c), (c, b)]
    return np.asarray(triangles, dtype=np.int64).reshape(-1, 3)


def flat_surface(points: FloatArray, loops: list[IntArray], max_loop: int = MAX_FLAT_LOOP
                 ) -> IntArray | None:
    """The least-area triangulation of each loop (:func:`min_area_triangles`) over the
    ``points`` (V, 3), as rows of point indices (T, 3); None when a loop is longer than
    ``max_loop`` or shorter than 3."""
    if not loops or any(len(loop) > max_loop or len(loop) < 3 for loop in loops):
        return None
    return np.concatenate([loop[min_area_triangles(points[loop])] for loop in loops])


def flat_positions(mesh: PolygonMesh, free: BoolArray, patch: BoolArray, base: FloatArray,
                   max_loop: int = MAX_FLAT_LOOP) -> FloatArray | None:
    """The ``base`` positions of the ``free`` vertices projected onto the least-area
    triangulation of each of the patch's border loops (:func:`min_area_triangles`): a
    flat patch spanned by the loop (what MeshFix-like fillers make), with the patch's
    own tessellation; None when a loop is not simple or longer than ``max_loop``."""
    loops = patch_loops(mesh, patch)
    if not loops or any(len(loop) > max_loop for loop in loops):
        return None
    corners = np.concatenate([mesh.vertices[loop][min_area_triangles(mesh.vertices[loop])]
                              for loop in loops if len(loop) >= 3])  # (T, 3, 3)
    if len(corners) == 0:
        return None
    rows = np.flatnonzero(free)
    x = np.asarray(base, dtype=np.float64)[rows]
    k = min(FLAT_NEIGHBOURS, len(corners))
    _, near = cKDTree(corners.mean(axis=1)).query(x, k=k)
    near = np.asarray(near).reshape(len(rows), k)
    closest = closest_points_on_triangles(np.repeat(x, k, axis=0),
                                          corners[near.reshape(-1)]).reshape(len(rows), k, 3)
    pick = np.linalg.norm(closest - x[:, None], axis=2).argmin(axis=1)
    out = np.asarray(base, dtype=np.float64).copy()
    out[rows] = closest[np.arange(len(rows)), pick]
    return out
