"""The vertex denoiser: a Point-E-style diffusion transformer with epsilon prediction.

Each vertex token is ``[x, y, z, m]`` (position and padding-mask channel, ``m = 1`` for
a real vertex and ``-1`` for padding) concatenated with the encoder's feature volumes
sampled trilinearly at the token's current (noisy) position. The timestep enters as one
extra token, as in Point-E. The output is the predicted noise of all four channels.

With ``local_points = K > 0`` each vertex token also attends, before every block, to the
``K`` conditioning points nearest its current position (:mod:`spacemesh.nn.local_points`);
the denoiser then takes the points as well.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from spacemesh.nn.local_points import (
    OFFSET_CHANNELS,
    LocalPointAttention,
    NeighbourFeatures,
    nearest_points,
)
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
    local_points : int
        ``K`` nearest conditioning points each token attends to before every block
        (0: none).
    local_width : int
        Hidden width of the neighbour features.
    normals : bool
        The conditioning points carry normals (6 channels), which the local-point
        attention reads too.
    """

    def __init__(
        self, *, width: int, layers: int, heads: int, feature_channels: int,
        point_voxel: tuple[tuple[int, int], ...] = (), local_points: int = 0,
        local_width: int = 32, normals: bool = False,
    ) -> None:
        super().__init__()
        self.width = width
        self.local_points = local_points
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
        if local_points:
            channels = OFFSET_CHANNELS + (3 if normals else 0)
            self.neighbour_features = NeighbourFeatures(channels=channels, width=local_width)
            self.local_attention = nn.ModuleList(
                LocalPointAttention(width=width, heads=heads, neighbour_width=local_width)
                for _ in range(layers)
            )

    def forward(
        self, x_t: Tensor, t: Tensor, volumes: list[Tensor], points: Tensor | None = None
    ) -> Tensor:
        """Predicted noise.

        Parameters
        ----------
        x_t : (B, N, 4) tensor
            Noisy positions and mask channel.
        t : (B,) tensor
            Timesteps (integer or float, in training-timestep units).
        volumes : list of (B, C_r, R_r, R_r, R_r) tensors
        points : (B, P, 3 or 6) tensor, optional
            The conditioning points (the encoder's input); needed with local points.

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
        if not self.local_points:
            h = self.ln_post(self.backbone(self.ln_pre(h)))
            return self.output_proj(h[:, 1:])
        if points is None:
            raise ValueError("this denoiser reads the conditioning points: pass points")
        neighbours = self.neighbour_features(
            nearest_points(positions, points, self.local_points).to(h.dtype))  # (B, N, K, L)
        h = self.ln_pre(h)
        for local, block in zip(self.local_attention, self.backbone.blocks, strict=True):
            tokens = h[:, 1:]
            h = torch.cat([h[:, :1], tokens + local(tokens, neighbours)], dim=1)
            h = block(h)
        return self.output_proj(self.ln_post(h)[:, 1:])



@torch.no_grad()
def graft_denoiser(source: VertexDenoiser, target: VertexDenoiser) -> None:
    """Start ``target`` as ``source``: copy the weights they share and silence the rest.

    ``target`` may add local-point attention to ``source``'s architecture; its output
    projections start at zero, so the grafted denoiser computes exactly ``source``'s
    prediction until training opens the local view (a warm start: the new branch learns
    what the volumes miss instead of a fresh denoiser relearning what they give).

    Parameters
    ----------
    source : VertexDenoiser
        A trained denoiser (volumes only, or the same architecture as ``target``).
    target : VertexDenoiser
        Changed in place.

    Raises
    ------
    ValueError
        The two differ in more than the local-point attention.
    """
    wanted = target.state_dict()
    given = source.state_dict()
    resized = [k for k, v in given.items() if k in wanted and wanted[k].shape != v.shape]
    if resized:
        raise ValueError(f"cannot graft the denoiser: {', '.join(resized)} differ in shape")
    missing, unexpected = target.load_state_dict(given, strict=False)
    added = ("neighbour_features.", "local_attention.")
    wrong = [k for k in missing if not k.startswith(added)] + list(unexpected)
    if wrong:
        raise ValueError(f"cannot graft the denoiser: {', '.join(wrong)} do not fit")
    if missing:
        for local in target.local_attention:
            local.proj.weight.zero_()
            local.proj.bias.zero_()
