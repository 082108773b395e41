"""Extraction of each vertex's cyclic order from its normalised matrix (paper Sec. 3.3).

For every vertex: solve the linear assignment problem on ``-Phi_bar``; if the optimal
permutation is one cycle over all neighbours, take it; otherwise fall back on the greedy
single-orbit matching, which adds entries in order of increasing cost and skips any entry
that would close a cycle shorter than the degree.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment

from spacemesh.typed import BoolArray, FloatArray, IntArray

#: ``fallback(rows) -> (len(rows), d)`` replacement cycles (see :func:`match_cycles`).
FallbackFn = Callable[[IntArray], IntArray]


def is_single_cycle(perm: IntArray) -> bool:
    """True when the permutation ``perm`` (d,) is one cycle through all d elements."""
    d = len(perm)
    seen, node = 1, int(perm[0]) if d else 0
    while node != 0 and seen <= d:
        node = int(perm[node])
        seen += 1
    return seen == d


def single_cycle_mask(perms: IntArray) -> BoolArray:
    """(B,) whether each row of ``perms`` (B, d) is a single d-cycle (vectorised)."""
    b, d = perms.shape
    rows = np.arange(b)
    node = perms[:, 0].copy()
    returned_early = np.zeros(b, dtype=bool)
    for _ in range(d - 1):
        returned_early |= node == 0
        node = perms[rows, node]
    return (node == 0) & ~returned_early


def greedy_single_cycle(cost: FloatArray) -> IntArray:
    """Lowest-cost-first matching constrained to a single cycle.

    Parameters
    ----------
    cost : (d, d) array
        Cost of matching row ``a`` to column ``b``. The diagonal is never used.

    Returns
    -------
    (d,) int64
        ``perm[a] = b``, a single cycle through all d elements.
    """
    d = len(cost)
    if d < 2:
        return np.zeros(d, dtype=np.int64)
    flat = np.where(np.eye(d, dtype=bool), np.inf, np.nan_to_num(cost, nan=np.inf))
    order = np.argsort(flat, axis=None, kind="stable")
    order = order[order // d != order % d].tolist()  # never a fixed point
    succ = [-1] * d
    has_pred = [False] * d
    # fragments are paths; path_start[tail] is its head and path_end[head] its tail
    path_start = list(range(d))
    path_end = list(range(d))
    added = 0
    for entry in order:
        a, b = divmod(entry, d)
        if succ[a] >= 0 or has_pred[b]:
            continue
        head_of_a = path_start[a]
        if head_of_a == b and added < d - 1:
            continue  # would close a cycle shorter than d
        succ[a] = b
        has_pred[b] = True
        added += 1
        if added == d:
            break
        tail_of_b = path_end[b]
        path_end[head_of_a] = tail_of_b
        path_start[tail_of_b] = head_of_a
    return np.asarray(succ, dtype=np.int64)


def match_cycles(
    log_phi_bar: FloatArray, fallback: FallbackFn | None = None
) -> tuple[IntArray, int]:
    """Single-orbit matchings for a batch of same-degree vertices.

    Parameters
    ----------
    log_phi_bar : (B, d, d) array
        Log of the Sinkhorn-normalised matrices.
    fallback : callable, optional
        ``fallback(rows) -> (len(rows), d)`` single-cycle permutations for the rows whose
        assignment is not a single orbit (default: :func:`greedy_single_cycle` on each).

    Returns
    -------
    perms : (B, d) int64
        ``perms[n, a] = b``: the neighbour after neighbour ``a`` around vertex ``n``.
    n_fallbacks : int
        How many vertices needed the greedy fallback.
    """
    b, d, _ = log_phi_bar.shape
    if d == 2:
        return np.tile(np.array([1, 0], dtype=np.int64), (b, 1)), 0
    if d < 2:
        return np.zeros((b, d), dtype=np.int64), 0
    cost = -np.exp(log_phi_bar)  # (B, d, d), -Phi_bar, diagonal = 0 (excluded by Sinkhorn)
    cost[:, np.arange(d), np.arange(d)] = np.inf
    perms = np.empty((b, d), dtype=np.int64)
    finite_cost = np.where(np.isfinite(cost), cost, 1e9)
    for n in range(b):
        _, cols = linear_sum_assignment(finite_cost[n])
        perms[n] = cols
    ok = single_cycle_mask(perms)
    bad = np.flatnonzero(~ok)
    if fallback is not None and bad.size:
        perms[bad] = fallback(bad)
    else:
        for row in bad:
            perms[row] = greedy_single_cycle(cost[row])
    return perms, len(bad)
