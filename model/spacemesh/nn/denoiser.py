"""The vertex denoiser: a Point-E-style diffusion transformer with epsilon prediction.

Each vertex token is ``[x, y, z, m]`` (position and padding-mask channel, ``m = 1`` for
a real vertex and ``-1`` for padding) concatenated with the encoder's feature volumes
sampled trilinearly at the token's current (noisy) position. The timestep enters as one
extra token, as in Point-E. The output is the predicted noise of all four channels.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from spacemesh.nn.pvcnn import PointVoxelStack, sample_volumes
from spacemesh.nn.transformer import Transformer, timestep_embedding

#: Channels of a vertex token: position and mask.
VERTEX_CHANNELS = 4


class VertexDenoiser(nn.Module):
    """Predicts the noise ``eps`` of noisy vertex tokens.

    Parameters
    ----------
    width, layers, heads : int
        Transformer size.
    feature_channels : int
        Sum of the encoder volumes' channels.
    point_voxel : tuple of (resolution, channels)
        Optional PVConv layers on the tokens (the paper's denoiser has them).
    """

    def __init__(
        self, *, width: int, layers: int, heads: int, feature_channels: int,
        point_voxel: tuple[tuple[int, int], ...] = (),
    ) -> None:
        super().__init__()
        self.width = width
        self.input_proj = nn.Linear(VERTEX_CHANNELS + feature_channels, width)
        self.point_voxel = PointVoxelStack(width=width, layers=point_voxel)
        self.time_embed = nn.Sequential(
            nn.Linear(width, width), nn.GELU(), nn.Linear(width, width)
        )
        self.ln_pre = nn.LayerNorm(width)
        self.backbone = Transformer(width=width, layers=layers, heads=heads)
        self.ln_post = nn.LayerNorm(width)
        self.output_proj = nn.Linear(width, VERTEX_CHANNELS)
        nn.init.normal_(self.output_proj.weight, std=0.1 / math.sqrt(width))
        nn.init.zeros_(self.output_proj.bias)

    def forward(self, x_t: Tensor, t: Tensor, volumes: list[Tensor]) -> Tensor:
        """Predicted noise.

        Parameters
        ----------
        x_t : (B, N, 4) tensor
            Noisy positions and mask channel.
        t : (B,) tensor
            Timesteps (integer or float, in training-timestep units).
        volumes : list of (B, C_r, R_r, R_r, R_r) tensors

        Returns
        -------
        (B, N, 4) tensor
        """
        positions = x_t[..., :3]
        features = sample_volumes(volumes, positions)  # (B, N, F)
        h = self.input_proj(torch.cat([x_t, features], dim=-1))  # (B, N, W)
        h = self.point_voxel(h, positions)
        temb = self.time_embed(timestep_embedding(t, self.width).to(h.dtype))  # (B, W)
        h = torch.cat([temb[:, None, :].to(h.dtype), h], dim=1)  # (B, 1 + N, W)
        h = self.ln_post(self.backbone(self.ln_pre(h)))
        return self.output_proj(h[:, 1:])

