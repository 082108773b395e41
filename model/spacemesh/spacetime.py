"""Adjacency embeddings: the spacetime distance (paper Eq. 2) and the edges it implies.

An embedding ``x_i`` of size ``k`` is split into ``n_space`` space and ``k - n_space`` time
coordinates; ``d(x_i, x_j) = |s_i - s_j|^2 - |t_i - t_j|^2`` and ``{i, j}`` is an edge when
``d < tau``. The ablation distances of the paper's Fig. 6 are also here: squared Euclidean
and negative dot product.

The pairwise distances are computed as one fused matrix product per block of rows:
``d_ij = a_i . b_j`` with augmented operands, so no dense ``N x N`` float matrix is ever held.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from spacemesh.typed import BoolArray, FloatArray, IntArray

Distance = Literal["spacetime", "euclidean", "dot"]
DISTANCES: tuple[str, ...] = ("spacetime", "euclidean", "dot")

#: Upper bound on the entries of one block of the distance matrix (64 MiB of float64).
BLOCK_ENTRIES = 8 * 1024 * 1024


def signature(k: int, n_space: int | None, distance: Distance) -> FloatArray:
    """(k,) metric signature: +1 for space coordinates, -1 for time coordinates.

    Parameters
    ----------
    k : int
        Embedding size.
    n_space : int or None
        Number of space coordinates (default ``k // 2``); only used by ``spacetime``.
    distance : {"spacetime", "euclidean", "dot"}

    Returns
    -------
    (k,) float64
    """
    if distance not in DISTANCES:
        raise ValueError(f"unknown distance {distance!r}; expected one of {DISTANCES}")
    g = np.ones(k)
    if distance == "spacetime":
        n_space = k // 2 if n_space is None else n_space
        g[n_space:] = -1.0
    return g


def distance_operands(
    x: FloatArray, distance: Distance = "spacetime", n_space: int | None = None
) -> tuple[FloatArray, FloatArray]:
    """Operands ``a, b`` with ``d(x_i, x_j) = a_i . b_j`` for every pair.

    Parameters
    ----------
    x : (N, k) array
        Adjacency embeddings.
    distance : {"spacetime", "euclidean", "dot"}
    n_space : int, optional
        Space coordinates for ``spacetime`` (default ``k // 2``).

    Returns
    -------
    a, b : (N, k + 2) float64
    """
    x = np.asarray(x, dtype=np.float64)
    n, k = x.shape
    if distance == "dot":
        return x, -x
    g = signature(k, n_space, distance)
    q = (x * x) @ g  # (N,) signed squared norm
    one = np.ones((n, 1))
    a = np.concatenate([x * g, q[:, None], one], axis=1)
    b = np.concatenate([-2.0 * x, one, q[:, None]], axis=1)
    return a, b


def operand_distances(
    operands: tuple[FloatArray, FloatArray], i: IntArray, j: IntArray
) -> FloatArray:
    """Distances ``d(i, j) = a_i . b_j`` of index arrays ``i`` and ``j`` of one shape (or
    broadcastable shapes), from :func:`distance_operands`' ``(a, b)``.

    Parameters
    ----------
    operands : tuple of two (N, k') float arrays
    i, j : int arrays

    Returns
    -------
    float64 array of the broadcast shape of ``i`` and ``j``
    """
    a, b = operands
    return np.einsum("...k,...k->...", a[i], b[j])


def pairwise_distance(
    x: FloatArray,
    y: FloatArray | None = None,
    distance: Distance = "spacetime",
    n_space: int | None = None,
) -> FloatArray:
    """Dense distances between two small sets (tests, local neighbourhoods).

    Parameters
    ----------
    x : (N, k) array
    y : (M, k) array, optional
        Defaults to ``x``.
    distance : {"spacetime", "euclidean", "dot"}
    n_space : int, optional

    Returns
    -------
    (N, M) float64
    """
    x = np.asarray(x, dtype=np.float64)
    y = x if y is None else np.asarray(y, dtype=np.float64)
    if distance == "dot":
        return -(x @ y.T)
    g = signature(x.shape[1], n_space, distance)
    diff = x[:, None, :] - y[None, :, :]  # (N, M, k)
    return np.einsum("nmk,k->nm", diff * diff, g)


def edges_below_threshold(
    x: FloatArray,
    tau: float,
    distance: Distance = "spacetime",
    n_space: int | None = None,
    alive: BoolArray | None = None,
    max_degree: int | None = None,
    block_entries: int = BLOCK_ENTRIES,
) -> IntArray:
    """All pairs ``i < j`` with ``d(x_i, x_j) < tau``, computed block by block.

    Parameters
    ----------
    x : (N, k) array
        Adjacency embeddings.
    tau : float
        The (learned) threshold.
    distance : {"spacetime", "euclidean", "dot"}
    n_space : int, optional
        Space coordinates for ``spacetime`` (default ``k // 2``).
    alive : (N,) bool, optional
        Only vertices marked True take part.
    max_degree : int, optional
        Bound on the degree: when set, a pair is kept only if each endpoint is among the
        other's ``max_degree`` closest candidates (ties broken by index). This bounds the
        memory of decoding arbitrary embeddings; trained embeddings never reach it.
    block_entries : int
        Largest number of distance entries computed at once (memory bound).

    Returns
    -------
    (E, 2) int64
        Edges in original vertex indices, ``edges[:, 0] < edges[:, 1]``, sorted.
    """
    x = np.asarray(x, dtype=np.float64)
    index = np.arange(len(x)) if alive is None else np.flatnonzero(alive)
    a, b = distance_operands(x[index], distance, n_space)
    n = len(index)
    rows_per_block = max(1, block_entries // max(n, 1))
    found: list[IntArray] = []
    for start in range(0, n, rows_per_block):
        stop = min(n, start + rows_per_block)
        # capped: full rows (both directions needed); else only columns j >= start
        first = 0 if max_degree is not None else start
        block = a[start:stop] @ b[first:].T  # (rows, n - first)
        below = block < tau
        rows = np.arange(start, stop)
        below[rows - start, rows - first] = False  # no loops
        if max_degree is not None:
            below = _keep_closest(block, below, max_degree)
        ii, jj = np.nonzero(below)
        found.append(np.stack([ii + start, jj + first], axis=1))
    pairs = np.concatenate(found) if found else np.zeros((0, 2), np.int64)
    if max_degree is not None:  # mutual candidates only
        key = pairs[:, 0] * n + pairs[:, 1]
        mutual = np.isin(key, pairs[:, 1] * n + pairs[:, 0])
        pairs = pairs[mutual & (pairs[:, 0] < pairs[:, 1])]
    else:
        pairs = pairs[pairs[:, 0] < pairs[:, 1]]
    return index[pairs].astype(np.int64).reshape(-1, 2)


def count_pairs_below_threshold(
    x: FloatArray,
    tau: float,
    distance: Distance = "spacetime",
    n_space: int | None = None,
    block_entries: int = BLOCK_ENTRIES,
) -> int:
    """Number of pairs ``i < j`` with ``d(x_i, x_j) < tau``, without listing them.

    Parameters
    ----------
    x : (N, k) array
    tau : float
    distance, n_space, block_entries
        As in :func:`edges_below_threshold`.

    Returns
    -------
    int
    """
    a, b = distance_operands(x, distance, n_space)
    n = len(a)
    rows_per_block = max(1, block_entries // max(n, 1))
    total = 0
    for start in range(0, n, rows_per_block):
        block = a[start : start + rows_per_block] @ b[start:].T  # (rows, n - start)
        below = block < tau
        total += int(np.triu(below, k=1).sum())
    return total


def _keep_closest(block: FloatArray, below: BoolArray, max_degree: int) -> BoolArray:
    """Restrict each row of ``below`` to its ``max_degree`` smallest entries of ``block``."""
    crowded = np.flatnonzero(below.sum(axis=1) > max_degree)
    if crowded.size == 0:
        return below
    values = np.where(below[crowded], block[crowded], np.inf)
    keep = np.argsort(values, axis=1, kind="stable")[:, :max_degree]
    mask = np.zeros_like(values, dtype=bool)
    np.put_along_axis(mask, keep, True, axis=1)
    below[crowded] = mask
    return below
