"""Relative local geometry for the connectivity network, as permutation-equivariant features.

Whether two vertices share an edge depends on where the *other* vertices near them lie,
which a transformer reading absolute coordinates has to infer slowly. Two features give
each vertex that local picture directly, without any positional embedding (the tokens
stay a set, and every feature is a function of relative positions only):

:func:`offset_moments`
    For every attention head, the mean and the covariance of the offsets
    ``p_j - p_i`` under that head's attention weights ``a_ij``: a soft, learned
    neighbourhood's centroid direction and shape (its normal is the covariance's
    smallest axis).
:func:`neighbour_offsets`
    The offsets to the ``K`` nearest vertices, nearest first, and their squared lengths:
    the exact local arrangement.

Both are plain tensor ops (matmul, top-k, gather) and export to standard ONNX.
"""

from __future__ import annotations

import torch
from torch import Tensor

#: Offsets are multiplied by this (typical edges are 0.1-0.5 long in the [-1, 1] frame).
OFFSET_SCALE = 4.0

#: Where padding vertices and missing neighbours are put, far outside the [-1, 1] frame.
FAR = 10.0

#: Channels of :func:`offset_moments` per head (3 mean, 6 covariance).
MOMENT_CHANNELS = 9


def _outer_upper(a: Tensor, b: Tensor) -> Tensor:
    """``a_x b_x, a_y b_y, a_z b_z, a_x b_y, a_x b_z, a_y b_z`` of ``(..., 3)`` tensors."""
    return torch.stack([a[..., 0] * b[..., 0], a[..., 1] * b[..., 1], a[..., 2] * b[..., 2],
                        a[..., 0] * b[..., 1], a[..., 0] * b[..., 2], a[..., 1] * b[..., 2]], -1)


def offset_moments(weights: Tensor, positions: Tensor) -> Tensor:
    """Mean and covariance of the offsets to the attended vertices, per head.

    With ``m_i = sum_j a_ij p_j`` and ``S_i = sum_j a_ij p_j p_j^T`` (rows of ``a`` sum to
    one), the mean offset is ``m_i - p_i`` and the second moment of the offsets is
    ``S_i - p_i m_i^T - m_i p_i^T + p_i p_i^T``: two matmuls, no ``N x N x 3`` tensor.

    Parameters
    ----------
    weights : (B, H, N, N) tensor
        Attention weights (rows sum to one).
    positions : (B, N, 3) tensor

    Returns
    -------
    (B, N, 9 H) tensor
        Per head: the mean offset (3) times :data:`OFFSET_SCALE`, then the upper triangle
        of the offsets' second moment (6) times its square.
    """
    p = positions.to(weights.dtype)
    b, h, n, _ = weights.shape
    lifted = torch.cat([p, _outer_upper(p, p)], dim=-1)[:, None]  # (B, 1, N, 9)
    moments = weights @ lifted  # (B, H, N, 9)
    mean, second = moments[..., :3], moments[..., 3:]
    pi = p[:, None]  # (B, 1, N, 3)
    cross = _outer_upper(pi, mean) + _outer_upper(mean, pi)  # (B, H, N, 6)
    covariance = second - cross + _outer_upper(pi, pi)
    features = torch.cat([(mean - pi) * OFFSET_SCALE, covariance * OFFSET_SCALE**2], dim=-1)
    return features.permute(0, 2, 1, 3).reshape(b, n, h * MOMENT_CHANNELS)


def neighbour_offsets(positions: Tensor, valid: Tensor, k: int) -> Tensor:
    """Offsets to each vertex's ``k`` nearest other real vertices, nearest first.

    ``k`` far-away dummy vertices are appended before the top-k, so any vertex count
    works (fewer than ``k`` real neighbours leave the last slots at the dummies, whose
    offsets are clamped), and padding vertices are moved far away first.

    Parameters
    ----------
    positions : (B, N, 3) tensor
    valid : (B, N) bool tensor
    k : int

    Returns
    -------
    (B, N, 4 k) tensor
        Per neighbour: the offset (3) times :data:`OFFSET_SCALE`, then its squared
        length times the square, both clamped to the frame.
    """
    p = positions.float()
    b, n, _ = p.shape
    keys = torch.cat([torch.where(valid[..., None], p, FAR), p.new_full((b, k, 3), FAR)], 1)
    d2 = (p[:, :, None, :] - keys[:, None, :, :]).square().sum(-1)  # (B, N, N + k)
    index = torch.arange(n, device=p.device)
    self_pair = index[:, None] == torch.arange(n + k, device=p.device)[None, :]  # (N, N + k)
    d2 = torch.where(self_pair[None], torch.full_like(d2, 4 * FAR**2), d2)
    nearest, slot = torch.topk(d2, k, dim=-1, largest=False)  # (B, N, k)
    gathered = torch.gather(keys[:, None].expand(b, n, n + k, 3), 2,
                            slot[..., None].expand(b, n, k, 3))  # (B, N, k, 3)
    offsets = ((gathered - p[:, :, None]) * OFFSET_SCALE).clamp(-2 * OFFSET_SCALE,
                                                                2 * OFFSET_SCALE)
    lengths = (nearest * OFFSET_SCALE**2).clamp(max=4 * OFFSET_SCALE**2)[..., None]
    return torch.cat([offsets, lengths], dim=-1).flatten(-2)
