"""Consistently oriented normals of bare points (numpy and scipy only).

:func:`oriented_normals` fits a plane to each point's neighbours
(:func:`spacemesh.geometry.fitting.estimate_point_normals`), then orients the normals
consistently by Hoppe et al.'s propagation (SIGGRAPH 1992): along a minimum spanning
tree of the :data:`ORIENT_NEIGHBOURS`-nearest-neighbour graph, weighted by
``1 - |n_i . n_j|`` so that orientation travels between near-parallel normals first,
each normal takes the sign that agrees with its parent's. Propagation fixes the
*relative* signs within each connected group; the global sign of each group is chosen
so that most of its normals point away from the centroid of all the points (right for
the outside of objects, which is what scanners see).

A caller that knows some signs (``votes``: a closed mesh's outward faces near a point,
where they agree) gives them: those points keep their vote, and the rest take the
propagated sign, with each group's global sign chosen by the majority of its votes
(the centroid rule only for groups without any). Open3D's
``orient_normals_consistent_tangent_plane`` does the same; the serving install has
no Open3D.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree
from scipy.spatial import cKDTree

from spacemesh.geometry.fitting import estimate_point_normals
from spacemesh.typed import FloatArray

#: Neighbours of the orientation graph.
ORIENT_NEIGHBOURS = 10
#: Added to every edge weight, so that parallel normals still make an edge.
_WEIGHT_FLOOR = 1e-6


def oriented_normals(points: FloatArray, normals: FloatArray | None = None,
                     votes: FloatArray | None = None, k: int = ORIENT_NEIGHBOURS
                     ) -> FloatArray:
    """Unit normals of ``points``, consistently oriented (see the module docstring).

    Parameters
    ----------
    points : (P, 3) float
        Finite points.
    normals : (P, 3) float, optional
        Their unoriented unit normals (plane fits when None).
    votes : (P,) float, optional
        +1 or -1: the sign a point's normal must take; 0: unknown.
    k : int
        Neighbours of the orientation graph.

    Returns
    -------
    (P, 3) float64
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    normals = (estimate_point_normals(points) if normals is None
               else np.asarray(normals, dtype=np.float64))  # (P, 3), signs arbitrary
    n = len(points)
    votes = np.zeros(n) if votes is None else np.sign(np.asarray(votes, dtype=np.float64))
    k = min(k, n - 1)
    if k < 1:
        return normals * np.where(votes < 0, -1.0, 1.0)[:, None]
    _, near = cKDTree(points).query(points, k=k + 1)
    rows = np.repeat(np.arange(n), k)
    cols = near[:, 1:].reshape(-1)
    weight = 1.0 - np.abs(np.einsum("ij,ij->i", normals[rows], normals[cols])) + _WEIGHT_FLOOR
    graph = sp.coo_matrix((weight, (rows, cols)), shape=(n, n)).tocsr()
    tree = minimum_spanning_tree(graph.maximum(graph.T))
    tree = tree.maximum(tree.T)  # undirected
    groups, label = connected_components(tree, directed=False)
    sign = np.ones(n)
    for group in range(groups):
        root = int(np.flatnonzero(label == group)[0])
        order, parent = breadth_first_order(tree, root, directed=False)
        for node in order[1:]:  # parents come first in breadth-first order
            agree = normals[node] @ normals[parent[node]] * sign[parent[node]]
            sign[node] = 1.0 if agree >= 0 else -1.0
    # each group's global sign: the majority of its votes, else away from the centroid
    voted = np.bincount(label, sign * votes, minlength=groups)  # (groups,)
    outward = np.einsum("ij,ij->i", normals * sign[:, None],
                        points - points.mean(axis=0)) > 0  # (P,)
    share = np.bincount(label, outward, minlength=groups) / np.bincount(label, minlength=groups)
    flip = np.where(voted != 0, voted < 0, share < 0.5)  # (groups,)
    sign = sign * np.where(flip[label], -1.0, 1.0)
    sign = np.where(votes != 0, votes, sign)  # a vote is kept as it is
    return normals * sign[:, None]
