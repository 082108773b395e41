"""The denoiser's close view of the input: attention over each vertex's nearest points.

The feature volumes show the denoiser the points at 16³ and 8³, so a vertex cannot be
placed more precisely than a voxel. Here every vertex token also reads the ``K`` input
points nearest its current (noisy) position at full resolution, as the connectivity
network reads its nearest vertices (:func:`spacemesh.nn.geometry.neighbour_offsets`):

:func:`nearest_points`
    The offsets to the ``K`` nearest input points, nearest first, their squared lengths,
    and the points' normals when the cloud has them. A top-k over the distances to all
    points, plain tensor ops (MatMul, TopK, GatherElements), so the lookup runs inside
    the exported ONNX graph; 2,048 points by 256 vertices is a small matrix.
:class:`LocalPointAttention`
    One multi-head attention of each token over its ``K`` points (keys and values: the
    neighbour features; the query from the token), added to the token. The
    denoiser puts one before every transformer block; the neighbour features are
    computed once per forward pass (:class:`NeighbourFeatures`).

Everything is relative to the vertex (offsets, not absolute coordinates), so the token
set stays permutation-equivariant.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from spacemesh.nn.geometry import OFFSET_SCALE
from spacemesh.nn.transformer import init_linear

#: Channels of a neighbour without normals: the scaled offset (3) and squared length (1).
OFFSET_CHANNELS = 4


def nearest_points(positions: Tensor, points: Tensor, k: int) -> Tensor:
    """Features of the ``k`` input points nearest each position, nearest first.

    Parameters
    ----------
    positions : (B, N, 3) tensor
        Vertex positions (noisy ones may lie outside [-1, 1]).
    points : (B, P, 3 or 6) tensor
        The conditioning points, with unit normals in the last three channels when 6.
        ``P >= k``.
    k : int

    Returns
    -------
    (B, N, k, 4 or 7) tensor
        Per neighbour: the offset ``q - p`` times :data:`OFFSET_SCALE`, its squared
        length times the square (both clamped to the frame), then the normal if any.
    """
    p = positions.float()
    q = points.float()
    b, n, _ = p.shape
    c = q.shape[-1]
    xyz = q[..., :3]
    # |p - q|^2 by one matmul, without a (B, N, P, 3) tensor
    d2 = (p.square().sum(-1, keepdim=True) + xyz.square().sum(-1)[:, None, :]
          - 2.0 * p @ xyz.transpose(1, 2)).clamp_min(0.0)  # (B, N, P)
    nearest, index = torch.topk(d2, k, dim=-1, largest=False)  # (B, N, k)
    flat = index.reshape(b, n * k, 1).expand(b, n * k, c)
    gathered = torch.gather(q, 1, flat).reshape(b, n, k, c)  # (B, N, k, C)
    offsets = ((gathered[..., :3] - p[:, :, None]) * OFFSET_SCALE).clamp(
        -2 * OFFSET_SCALE, 2 * OFFSET_SCALE)
    lengths = (nearest * OFFSET_SCALE**2).clamp(max=4 * OFFSET_SCALE**2)[..., None]
    return torch.cat([offsets, lengths, gathered[..., 3:]], dim=-1)


class NeighbourFeatures(nn.Module):
    """A small MLP on each neighbour's raw features, shared by all attention layers.

    Parameters
    ----------
    channels : int
        Raw channels per neighbour (4, or 7 with normals).
    width : int
        Hidden width.
    """

    def __init__(self, *, channels: int, width: int) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Linear(channels, width), nn.GELU(),
                                 nn.Linear(width, width), nn.GELU())

    def forward(self, raw: Tensor) -> Tensor:
        """``(B, N, K, channels)`` to ``(B, N, K, width)``."""
        return self.net(raw)


class LocalPointAttention(nn.Module):
    """Each token attends to its own ``K`` neighbours (multi-head, softmax over ``K``).

    The keys and values are the neighbour features themselves (width ``L``, small): the
    query of head ``h`` is projected to ``L`` channels, the head pools the neighbour
    features with its weights, and one linear layer maps the ``H`` pooled vectors to the
    token width. That is attention with the key and value projections folded into the
    query and output projections, and it never makes a ``(B, N, K, W)`` tensor.

    Parameters
    ----------
    width, heads : int
        Token width and heads.
    neighbour_width : int
        Width ``L`` of the neighbour features (:class:`NeighbourFeatures`).
    init_scale : float
        As in :class:`spacemesh.nn.transformer.MultiheadSelfAttention`.
    """

    def __init__(self, *, width: int, heads: int, neighbour_width: int,
                 init_scale: float = 0.25) -> None:
        super().__init__()
        self.heads = heads
        self.neighbour_width = neighbour_width
        self.ln = nn.LayerNorm(width)
        self.query = nn.Linear(width, heads * neighbour_width)
        self.proj = nn.Linear(heads * neighbour_width, width)
        init_linear(self.query, init_scale / math.sqrt(width))
        init_linear(self.proj, init_scale / math.sqrt(heads * neighbour_width))

    def forward(self, h: Tensor, neighbours: Tensor) -> Tensor:
        """The update ``(B, N, W)`` of tokens ``h`` ``(B, N, W)`` from their neighbour
        features ``(B, N, K, L)`` (to be added to ``h``)."""
        b, n, _ = h.shape
        width = self.neighbour_width
        q = self.query(self.ln(h)).reshape(b, n, self.heads, width)  # (B, N, H, L)
        scores = (q @ neighbours.transpose(-1, -2)).float() * (1.0 / math.sqrt(width))
        weights = torch.softmax(scores, dim=-1).to(neighbours.dtype)  # (B, N, H, K)
        pooled = weights @ neighbours  # (B, N, H, L)
        return self.proj(pooled.reshape(b, n, self.heads * width))
