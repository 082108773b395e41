"""Geometric cyclic orders: neighbours sorted by angle around a fitted normal.

The decode's fallback for a vertex whose optimal assignment is not a single orbit (the
paper, Sec. 3.3, takes a greedy single orbit there). When positions are known, the order
of the neighbours around the vertex is usually right for a surface: it is one orbit by
construction, and neighbouring fallback vertices agree with each other, so their faces
close instead of wandering. Geometry fixes the cycle; the learned ``Phi_bar`` picks its
direction (:func:`oriented_angular_cycles`), so no outward normal is needed.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray, IntArray


def angular_cycles(positions: FloatArray, vertices: IntArray, neighbours: IntArray) -> IntArray:
    """One cyclic order per vertex: its neighbours by angle around the local plane's normal.

    Parameters
    ----------
    positions : (N, 3) float
    vertices : (B,) int
        Vertices of one degree ``d``.
    neighbours : (B, d) int
        Their neighbours, in slot order.

    Returns
    -------
    (B, d) int64
        ``perms[n, a] = b``: the slot after slot ``a`` (one cycle; its direction depends
        on the arbitrary sign of the fitted normal).
    """
    positions = np.asarray(positions, dtype=np.float64)
    b, d = neighbours.shape
    offsets = positions[neighbours] - positions[vertices][:, None, :]  # (B, d, 3)
    centred = offsets - offsets.mean(axis=1, keepdims=True)
    _, vecs = np.linalg.eigh(np.einsum("bdi,bdj->bij", centred, centred))  # (B, 3, 3)
    normal = vecs[:, :, 0]  # (B, 3): the direction of least spread
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(normal, u)
    angle = np.arctan2(np.einsum("bdi,bi->bd", offsets, v), np.einsum("bdi,bi->bd", offsets, u))
    order = np.argsort(angle, axis=1, kind="stable")  # (B, d)
    perms = np.empty((b, d), dtype=np.int64)
    perms[np.arange(b)[:, None], order] = np.roll(order, -1, axis=1)
    return perms


def oriented_angular_cycles(
    positions: FloatArray, vertices: IntArray, neighbours: IntArray, log_phi_bar: FloatArray
) -> IntArray:
    """:func:`angular_cycles`, each in the direction that ``Phi_bar`` prefers.

    Parameters
    ----------
    positions, vertices, neighbours
        See :func:`angular_cycles`.
    log_phi_bar : (B, d, d) float
        The vertices' log Sinkhorn-normalised matrices.

    Returns
    -------
    (B, d) int64
        Of the cycle and its reverse, the one with the larger ``sum_a Phi_bar[a, perm[a]]``.
    """
    forward = angular_cycles(positions, vertices, neighbours)  # (B, d)
    b, d = forward.shape
    backward = np.empty_like(forward)
    rows = np.arange(b)[:, None]
    backward[rows, forward] = np.arange(d)[None, :]  # the inverse permutation
    phi = np.exp(np.nan_to_num(log_phi_bar, nan=-np.inf))  # (B, d, d)
    slots = np.arange(d)[None, :]
    score_f = phi[rows, slots, forward].sum(axis=1)
    score_b = phi[rows, slots, backward].sum(axis=1)
    return np.where((score_b > score_f)[:, None], backward, forward)
