"""Permutation embeddings: the reduction F (paper Eq. 6), the matrices Phi, and Sinkhorn.

For a vertex ``i`` with neighbours ``n_0 .. n_{d-1}`` (sorted by index), the ``d x d``
matrix of logits is ``L^i[a, b] = F(y_root[i], y_prev[n_a], y_next[n_b])`` and
``Phi^i = exp(L^i)``. Row ``a`` is the halfedge arriving from ``n_a``; column ``b`` is the
halfedge leaving towards ``n_b``. A fixed point (``a == b``) can never be part of a
single cyclic orbit of length ``d >= 2``, so the diagonal is excluded (logit ``-inf``)
before normalisation, here and in the losses alike.

Sinkhorn runs in the log domain, batched over all vertices of equal degree.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from spacemesh.typed import FloatArray, IntArray

Reduction = Literal["product", "sum", "max", "concat"]
REDUCTIONS: tuple[str, ...] = ("product", "sum", "max", "concat")

#: Default number of Sinkhorn iterations (row + column normalisation each).
SINKHORN_ITERS = 20


def reduction_logits(
    root: FloatArray,
    prev: FloatArray,
    nxt: FloatArray,
    reduction: Reduction = "product",
    params: dict[str, FloatArray] | None = None,
) -> FloatArray:
    """Logits ``L[n, a, b] = F(root[n], prev[n, a], nxt[n, b])`` for a batch of vertices.

    Parameters
    ----------
    root : (B, kp) array
        Root embeddings of the centre vertices.
    prev : (B, d, kp) array
        Prev embeddings of each centre's neighbours.
    nxt : (B, d, kp) array
        Next embeddings of each centre's neighbours.
    reduction : {"product", "sum", "max", "concat"}
        ``product`` is Eq. 6, ``sum(root * prev * next)``. ``sum`` is ``sum(root + prev +
        next)``, ``max`` is ``sum(max(root, prev, next))`` (elementwise), ``concat`` is a
        one-hidden-layer MLP on ``[root, prev, next]`` whose weights are in ``params``
        (``w1`` (3 kp, h), ``b1`` (h,), ``w2`` (h,)).
    params : dict, optional
        Weights of the ``concat`` reduction.

    Returns
    -------
    (B, d, d) float64
    """
    root = np.asarray(root, dtype=np.float64)
    prev = np.asarray(prev, dtype=np.float64)
    nxt = np.asarray(nxt, dtype=np.float64)
    if reduction == "product":
        return np.einsum("bak,bk,bck->bac", prev, root, nxt)
    if reduction == "sum":
        return root.sum(-1)[:, None, None] + prev.sum(-1)[:, :, None] + nxt.sum(-1)[:, None, :]
    if reduction == "max":
        stacked = np.maximum(prev[:, :, None, :], nxt[:, None, :, :])
        return np.maximum(stacked, root[:, None, None, :]).sum(-1)
    if reduction == "concat":
        if params is None:
            raise ValueError("the concat reduction needs its MLP weights in params")
        w1 = np.asarray(params["w1"], dtype=np.float64)
        kp = root.shape[-1]
        hidden = (
            (root @ w1[:kp])[:, None, None, :]
            + (prev @ w1[kp : 2 * kp])[:, :, None, :]
            + (nxt @ w1[2 * kp :])[:, None, :, :]
            + np.asarray(params["b1"], dtype=np.float64)
        )
        return np.maximum(hidden, 0.0) @ np.asarray(params["w2"], dtype=np.float64)
    raise ValueError(f"unknown reduction {reduction!r}; expected one of {REDUCTIONS}")


def _logsumexp(x: FloatArray, axis: int) -> FloatArray:
    peak = np.max(x, axis=axis, keepdims=True)
    peak = np.where(np.isfinite(peak), peak, 0.0)
    return np.log(np.sum(np.exp(x - peak), axis=axis, keepdims=True)) + peak


def mask_diagonal(logits: FloatArray) -> FloatArray:
    """Copy of ``logits`` (B, d, d) with the diagonal set to ``-inf`` (when ``d >= 2``)."""
    out = np.array(logits, dtype=np.float64, copy=True)
    d = out.shape[-1]
    if d >= 2:
        out[:, np.arange(d), np.arange(d)] = -np.inf
    return out


def log_sinkhorn(logits: FloatArray, n_iters: int = SINKHORN_ITERS) -> FloatArray:
    """Log-domain Sinkhorn normalisation of a batch of square matrices.

    Parameters
    ----------
    logits : (B, d, d) array
        ``log Phi``; entries may be ``-inf`` (excluded).
    n_iters : int
        Number of (row, column) normalisation rounds.

    Returns
    -------
    (B, d, d) float64
        ``log Phi_bar``: rows and columns of ``exp`` sum to one (up to convergence).
    """
    log_p = np.asarray(logits, dtype=np.float64)
    log_p = np.nan_to_num(log_p, nan=0.0, posinf=1e30, neginf=-np.inf)
    for _ in range(n_iters):
        log_p = log_p - _logsumexp(log_p, axis=2)
        log_p = log_p - _logsumexp(log_p, axis=1)
    return log_p


def group_by_degree(offsets: IntArray) -> dict[int, IntArray]:
    """Vertices grouped by degree.

    Parameters
    ----------
    offsets : (N + 1,) int64
        CSR offsets of the neighbour lists.

    Returns
    -------
    dict
        ``degree -> (n_d,) vertex indices``, for every degree present (0 included).
    """
    degree = np.diff(offsets)
    return {int(d): np.flatnonzero(degree == d) for d in np.unique(degree)}


def neighbourhood_log_phi_bar(
    root: FloatArray,
    prev: FloatArray,
    nxt: FloatArray,
    vertices: IntArray,
    offsets: IntArray,
    neighbours: IntArray,
    degree: int,
    reduction: Reduction = "product",
    params: dict[str, FloatArray] | None = None,
    n_iters: int = SINKHORN_ITERS,
) -> FloatArray:
    """``log Phi_bar`` for a group of vertices that share one degree.

    Parameters
    ----------
    root, prev, nxt : (N, kp) arrays
        Permutation embeddings of all vertices.
    vertices : (B,) int64
        Centre vertices, all of degree ``degree``.
    offsets, neighbours : CSR neighbour lists
    degree : int
    reduction, params, n_iters
        See :func:`reduction_logits` and :func:`log_sinkhorn`.

    Returns
    -------
    (B, degree, degree) float64
    """
    slots = offsets[vertices][:, None] + np.arange(degree)[None, :]  # (B, d)
    nbrs = neighbours[slots]  # (B, d)
    logits = reduction_logits(root[vertices], prev[nbrs], nxt[nbrs], reduction, params)
    return log_sinkhorn(mask_diagonal(logits), n_iters)
