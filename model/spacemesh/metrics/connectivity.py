"""Connectivity scores of a decode against the mesh it should reproduce (numpy only).

The two figures that ``spacemesh fit``, training and the decode experiments report:
edge F1 over undirected edges and the accuracy of the ``next`` relations (paper Sec. 4).
"""

from __future__ import annotations

import numpy as np

from spacemesh.connectivity import Connectivity


def edge_f1_score(predicted: np.ndarray, truth: np.ndarray, n_vertices: int) -> float:
    """F1 of two undirected edge sets given as (E, 2) arrays with ``i < j``.

    Parameters
    ----------
    predicted, truth : (E, 2) int
        Edges with the smaller index first.
    n_vertices : int
        The vertex count (to key the pairs).

    Returns
    -------
    float
        ``2 TP / (|predicted| + |truth|)``; 1.0 when both are empty.
    """
    key_p = predicted[:, 0].astype(np.int64) * n_vertices + predicted[:, 1]
    key_t = truth[:, 0].astype(np.int64) * n_vertices + truth[:, 1]
    tp = np.isin(key_p, key_t).sum()
    if len(key_p) + len(key_t) == 0:
        return 1.0
    return float(2 * tp / (len(key_p) + len(key_t)))


def next_accuracy(decoded: Connectivity, truth: Connectivity) -> float:
    """Fraction of ground-truth ``next`` relations ``(i, j, k)`` present in the decode.

    Parameters
    ----------
    decoded, truth : Connectivity
        On the same vertices.

    Returns
    -------
    float
        In [0, 1]; 1.0 when the truth has no relations.
    """
    n = truth.n_vertices
    t = truth.next_triplets()
    d = decoded.next_triplets()
    key_t = (t[:, 0] * n + t[:, 1]) * n + t[:, 2]
    key_d = (d[:, 0] * n + d[:, 1]) * n + d[:, 2]
    return float(np.isin(key_t, key_d).mean()) if len(key_t) else 1.0
