"""Graphs given as undirected node pairs: connected components and the uniform
(umbrella) adjacency, the one home of both (scipy.sparse)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from spacemesh.typed import ArrayLike, IntArray


def _pairs(pairs: ArrayLike) -> IntArray:
    """(E, 2) int64 ``pairs`` (an empty input of any shape gives (0, 2))."""
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


def component_labels(n_nodes: int, pairs: ArrayLike) -> tuple[int, IntArray]:
    """Connected components of the undirected graph on ``n_nodes`` nodes joined by
    ``pairs``.

    Labels are numbered in order of each component's first (smallest) node, as
    :func:`scipy.sparse.csgraph.connected_components` numbers them; a node in no pair is a
    component of its own. Repeated pairs and self pairs are allowed.

    Parameters
    ----------
    n_nodes : int
        Number of nodes N (may be 0).
    pairs : (E, 2) int
        Node pairs, in either order, each in ``[0, n_nodes)``.

    Returns
    -------
    n_components : int
    labels : (N,) int64
        Component of each node, in ``[0, n_components)``.
    """
    edges = _pairs(pairs)  # (E, 2)
    graph = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])),
                          shape=(n_nodes, n_nodes))  # (N, N)
    count, labels = connected_components(graph, directed=False)  # labels (N,) int32
    return int(count), labels.astype(np.int64)


def uniform_adjacency(n_nodes: int, pairs: ArrayLike) -> sp.csr_matrix:
    """The uniform (umbrella) weights ``W`` of a graph: 1.0 between every two nodes that
    a pair joins, in both directions, 0 elsewhere.

    ``W @ x / degree`` is the mean of each node's neighbours (``degree`` the row sums of
    ``W``), and ``I - D^-1 W`` the uniform Laplacian.

    Parameters
    ----------
    n_nodes : int
        Number of nodes N.
    pairs : (E, 2) int
        Node pairs, in either order; repeats count once.

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        Symmetric, with sorted indices.
    """
    edges = _pairs(pairs)  # (E, 2)
    directed = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])),
                             shape=(n_nodes, n_nodes)).tocsr()  # (N, N)
    return ((directed + directed.T) > 0).astype(np.float64)
