"""The connectivity network: per-vertex SpaceMesh embeddings from vertex positions.

A transformer without positional embedding reads each vertex's position concatenated
with the encoder volumes sampled there, and predicts for every vertex at once the
adjacency embedding ``x`` (``k``) and the permutation embeddings ``y_root``, ``y_prev``,
``y_next`` (``kp`` each); the edge threshold ``tau`` is one learned scalar. Padding
vertices are masked out of attention. An optional distance prior adds
``-s_h |p_i - p_j|^2`` to the logits of head ``h`` (learned ``s_h > 0``): relative and
permutation-equivariant, so the network stays a function of the vertex *set*. Two
optional local-geometry features (:mod:`spacemesh.nn.geometry`), also relative and
permutation-equivariant: the offsets to each vertex's ``K`` nearest vertices added to its
input, and geometric attention (each head's offset moments added to its output).
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor, nn

from spacemesh.nn.geometry import neighbour_offsets
from spacemesh.nn.pvcnn import PointVoxelStack, sample_volumes
from spacemesh.nn.transformer import Transformer, key_padding_bias


def fourier_features(positions: Tensor, octaves: int) -> list[Tensor]:
    """``sin`` and ``cos`` of ``pi 2^o p`` for ``o < octaves``: two ``(B, N, 3 octaves)``."""
    if octaves == 0:
        return []
    freqs = math.pi * 2.0 ** torch.arange(octaves, dtype=positions.dtype, device=positions.device)
    angles = (positions[..., None] * freqs).flatten(-2)  # (B, N, 3 octaves)
    return [torch.sin(angles), torch.cos(angles)]


#: Edge length the position prior's initial scale and threshold are set for.
PRIOR_EDGE_LENGTH = 0.3


class ConnectivityNet(nn.Module):
    """Predicts ``x``, ``y_root``, ``y_prev``, ``y_next`` and ``tau``.

    Parameters
    ----------
    width, layers, heads : int
        Transformer size.
    feature_channels : int
        Sum of the encoder volumes' channels.
    adjacency_dim, permutation_dim : int
        ``k`` and ``kp``.
    distance_bias : bool
        Use the learned distance prior in attention.
    fourier : int
        Octaves of coordinate sine/cosine features.
    position_prior : bool
        Add ``c p`` to the first three coordinates of ``x`` (they must be space
        coordinates) with a learned ``c``, and start from small network outputs.
    point_voxel : tuple of (resolution, channels)
        Optional PVConv layers on the tokens.
    neighbours : int
        ``K`` of the nearest-neighbour offsets added to each token (0: none).
    geometric_attention : bool
        Add each head's offset moments to its attention output.
    """

    def __init__(
        self, *, width: int, layers: int, heads: int, feature_channels: int,
        adjacency_dim: int, permutation_dim: int, distance_bias: bool = True, fourier: int = 0,
        position_prior: bool = False, point_voxel: tuple[tuple[int, int], ...] = (),
        neighbours: int = 0, geometric_attention: bool = False,
    ) -> None:
        super().__init__()
        self.adjacency_dim = adjacency_dim
        self.permutation_dim = permutation_dim
        self.heads = heads
        self.fourier = fourier
        self.neighbours = neighbours
        self.geometric_attention = geometric_attention
        self.input_proj = nn.Linear(3 + 6 * fourier + feature_channels, width)
        self.neighbour_mlp = (
            nn.Sequential(nn.Linear(4 * neighbours, width), nn.GELU(), nn.Linear(width, width))
            if neighbours else None
        )
        self.point_voxel = PointVoxelStack(width=width, layers=point_voxel)
        self.ln_pre = nn.LayerNorm(width)
        self.backbone = Transformer(width=width, layers=layers, heads=heads,
                                    geometry=geometric_attention)
        self.ln_post = nn.LayerNorm(width)
        self.output_proj = nn.Linear(width, adjacency_dim + 3 * permutation_dim)
        std = (0.1 if position_prior else 1.0) / math.sqrt(width)
        nn.init.normal_(self.output_proj.weight, std=std)
        nn.init.zeros_(self.output_proj.bias)
        if position_prior:
            # typical edges are ~0.3 long in the normalised frame: c |dp|^2 ~ 1 = tau
            self.position_scale = nn.Parameter(torch.tensor(1.0 / PRIOR_EDGE_LENGTH))
            self.tau = nn.Parameter(torch.ones(()))
        else:
            self.position_scale = None
            self.tau = nn.Parameter(torch.zeros(()))
        if distance_bias:
            # slopes spread geometrically over two decades (edge lengths are ~0.1-0.5)
            start = np.log(0.5) + np.arange(heads) * np.log(100.0) / max(heads - 1, 1)
            self.log_slope = nn.Parameter(torch.tensor(start, dtype=torch.float32))
        else:
            self.log_slope = None

    def attention_bias(self, vertices: Tensor, valid: Tensor) -> Tensor:
        """Additive attention bias ``(B, H or 1, N, N)`` from padding and distances."""
        bias = key_padding_bias(valid)  # (B, 1, 1, N)
        if self.log_slope is None:
            return bias
        p = vertices.float()
        d2 = (p[:, :, None, :] - p[:, None, :, :]).square().sum(-1)  # (B, N, N)
        slope = torch.exp(self.log_slope).reshape(1, -1, 1, 1)  # (1, H, 1, 1)
        return bias - slope * d2[:, None]

    def forward(
        self, vertices: Tensor, valid: Tensor, volumes: list[Tensor]
    ) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        """Per-vertex embeddings.

        Parameters
        ----------
        vertices : (B, N, 3) tensor
            Positions in [-1, 1] (padding anywhere).
        valid : (B, N) bool tensor
            Real vertices.
        volumes : list of (B, C_r, R_r, R_r, R_r) tensors

        Returns
        -------
        x : (B, N, k) tensor
        root, prev, next : (B, N, kp) tensors
        tau : (1,) tensor
        """
        features = sample_volumes(volumes, vertices)  # (B, N, F)
        inputs = [vertices, *fourier_features(vertices, self.fourier), features]
        h = self.input_proj(torch.cat(inputs, dim=-1))  # (B, N, W)
        if self.neighbour_mlp is not None:
            h = h + self.neighbour_mlp(neighbour_offsets(vertices, valid, self.neighbours))
        h = self.point_voxel(h, vertices)
        positions = vertices if self.geometric_attention else None
        bias = self.attention_bias(vertices, valid)
        h = self.ln_post(self.backbone(self.ln_pre(h), bias, positions))
        out = self.output_proj(h).float()  # (B, N, k + 3 kp)
        k, kp = self.adjacency_dim, self.permutation_dim
        x = out[..., :k]
        if self.position_scale is not None:
            pad = x.new_zeros(*x.shape[:-1], k - 3)
            x = x + torch.cat([self.position_scale * vertices.float(), pad], dim=-1)
        root = out[..., k : k + kp]
        prev = out[..., k + kp : k + 2 * kp]
        nxt = out[..., k + 2 * kp :]
        return x, root, prev, nxt, self.tau.reshape(1)
