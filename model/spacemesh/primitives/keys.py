"""Integer keys of undirected edges, the one way vertex pairs are compared and counted."""

from __future__ import annotations

import numpy as np

from spacemesh.typed import IntArray


def edge_keys(halfedges: IntArray, n_vertices: int) -> IntArray:
    """(S,) integer key ``min * V + max`` of the undirected edge of each vertex pair.

    Parameters
    ----------
    halfedges : (S, 2) int
        Vertex pairs, in either order.
    n_vertices : int

    Returns
    -------
    (S,) int64
    """
    lo = np.minimum(halfedges[:, 0], halfedges[:, 1])
    hi = np.maximum(halfedges[:, 0], halfedges[:, 1])
    return lo * max(n_vertices, 1) + hi
