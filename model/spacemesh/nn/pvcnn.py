"""PVCNN in pure torch: voxelise (scatter-mean), devoxelise (trilinear), PVConv, encoder.

Positions live in the normalised frame ``[-1, 1]^3``. A grid of resolution ``R`` puts
its voxel centres at ``-1 + 2 i / (R - 1)``; a position's continuous grid coordinate is
``g = (p + 1) (R - 1) / 2``. Voxelising averages the features of the points whose
rounded ``g`` is a voxel; devoxelising interpolates trilinearly between the 8 voxels
around ``g``. Both are written with flat indices (``index_add`` and one ``gather``),
so they export to plain ONNX ScatterND/Gather ops and need no custom kernels.

Volumes are laid out ``(B, C, R, R, R)`` with axes ``x, y, z``; the flat voxel index
is ``(i R + j) R + k``.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn


def grid_coordinates(positions: Tensor, resolution: int) -> Tensor:
    """Continuous grid coordinates ``(B, N, 3)`` in ``[0, R - 1]`` of positions in [-1, 1]."""
    g = (positions + 1.0) * (0.5 * (resolution - 1))
    return g.clamp(0.0, float(resolution - 1))


def voxelize(features: Tensor, positions: Tensor, resolution: int) -> Tensor:
    """Average point features into a voxel grid.

    Parameters
    ----------
    features : (B, N, C) tensor
    positions : (B, N, 3) tensor
        In ``[-1, 1]`` (clamped).
    resolution : int

    Returns
    -------
    (B, C, R, R, R) tensor
        Mean feature of the points in each voxel (zero where there are none).
    """
    b, _n, c = features.shape
    r = resolution
    ijk = torch.round(grid_coordinates(positions, r)).long()  # (B, N, 3)
    flat = (ijk[..., 0] * r + ijk[..., 1]) * r + ijk[..., 2]  # (B, N)
    batch = torch.arange(b, device=features.device).unsqueeze(1) * (r * r * r)
    index = (flat + batch).reshape(-1)  # (B N,)
    total = features.new_zeros(b * r * r * r, c).index_add(0, index, features.reshape(-1, c))
    ones = features.new_ones(index.shape[0], 1)
    count = features.new_zeros(b * r * r * r, 1).index_add(0, index, ones)
    mean = total / count.clamp_min(1.0)  # (B R^3, C)
    return mean.reshape(b, r, r, r, c).permute(0, 4, 1, 2, 3)


_CORNERS = ((0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1), (1, 0, 0), (1, 0, 1), (1, 1, 0), (1, 1, 1))


def devoxelize(volume: Tensor, positions: Tensor) -> Tensor:
    """Trilinear interpolation of a volume at positions.

    Parameters
    ----------
    volume : (B, C, R, R, R) tensor
    positions : (B, N, 3) tensor
        In ``[-1, 1]`` (clamped).

    Returns
    -------
    (B, N, C) tensor
    """
    b, c, r = volume.shape[0], volume.shape[1], volume.shape[2]
    n = positions.shape[1]
    g = grid_coordinates(positions, r)  # (B, N, 3)
    base = torch.floor(g).clamp(0.0, float(max(r - 2, 0)))
    frac = g - base  # (B, N, 3) in [0, 1]
    base = base.long()
    offsets = torch.tensor(_CORNERS, device=volume.device)  # (8, 3)
    corner = (base.unsqueeze(2) + offsets).clamp_max(r - 1)  # (B, N, 8, 3)
    flat = (corner[..., 0] * r + corner[..., 1]) * r + corner[..., 2]  # (B, N, 8)
    batch = torch.arange(b, device=volume.device).reshape(b, 1, 1) * (r * r * r)
    table = volume.permute(0, 2, 3, 4, 1).reshape(-1, c)  # (B R^3, C)
    values = table[(flat + batch).reshape(-1)].reshape(b, n, 8, c)  # (B, N, 8, C)
    off = offsets.to(frac.dtype)  # (8, 3)
    f = frac.unsqueeze(2)  # (B, N, 1, 3)
    weight = (off * f + (1.0 - off) * (1.0 - f)).prod(-1)  # (B, N, 8)
    return (values * weight.unsqueeze(-1)).sum(2)


def sample_volumes(volumes: list[Tensor] | tuple[Tensor, ...], positions: Tensor) -> Tensor:
    """Features of all volumes at positions, concatenated: ``(B, N, sum C_r)``."""
    return torch.cat([devoxelize(v, positions) for v in volumes], dim=-1)


class GroupNorm(nn.Module):
    """Group normalisation written with plain reductions.

    ``torch.nn.GroupNorm`` exports to an ONNX op whose onnxruntime kernel differs from
    torch by up to ~1e-3; the explicit form exports to ReduceMean/Sub/Div and agrees to
    float rounding.

    Parameters
    ----------
    groups, channels : int
    eps : float
    """

    def __init__(self, *, groups: int, channels: int, eps: float = 1e-5) -> None:
        super().__init__()
        self.groups = groups
        self.eps = eps
        self.weight = nn.Parameter(torch.ones(channels))
        self.bias = nn.Parameter(torch.zeros(channels))

    def forward(self, x: Tensor) -> Tensor:
        """Normalise ``x`` ``(B, C, ...)`` over each group of channels and all positions."""
        shape = x.shape
        h = x.reshape(shape[0], self.groups, -1).float()
        mean = h.mean(-1, keepdim=True)
        var = (h - mean).square().mean(-1, keepdim=True)
        h = ((h - mean) * torch.rsqrt(var + self.eps)).to(x.dtype).reshape(shape)
        view = (1, -1) + (1,) * (len(shape) - 2)
        return h * self.weight.reshape(view) + self.bias.reshape(view)


def _groups(channels: int) -> int:
    for g in (8, 4, 2):
        if channels % g == 0:
            return g
    return 1


class ConvBlock3d(nn.Module):
    """Two 3x3x3 convolutions with group norm and SiLU, plus a 1x1x1 skip."""

    def __init__(self, *, in_channels: int, out_channels: int) -> None:
        super().__init__()
        self.conv1 = nn.Conv3d(in_channels, out_channels, 3, padding=1)
        self.norm1 = GroupNorm(groups=_groups(out_channels), channels=out_channels)
        self.conv2 = nn.Conv3d(out_channels, out_channels, 3, padding=1)
        self.norm2 = GroupNorm(groups=_groups(out_channels), channels=out_channels)
        self.skip = (
            nn.Identity() if in_channels == out_channels
            else nn.Conv3d(in_channels, out_channels, 1)
        )
        self.act = nn.SiLU()

    def forward(self, x: Tensor) -> Tensor:
        """``(B, C_in, R, R, R)`` to ``(B, C_out, R, R, R)``."""
        h = self.act(self.norm1(self.conv1(x)))
        h = self.norm2(self.conv2(h))
        return self.act(h + self.skip(x))


class PVConv(nn.Module):
    """Point-voxel convolution: a voxel branch (voxelise, convolve, devoxelise) plus a
    per-point MLP branch, summed.

    Parameters
    ----------
    in_channels, out_channels, resolution : int
    """

    def __init__(self, *, in_channels: int, out_channels: int, resolution: int) -> None:
        super().__init__()
        self.resolution = resolution
        self.voxel = ConvBlock3d(in_channels=in_channels, out_channels=out_channels)
        self.point = nn.Sequential(
            nn.Linear(in_channels, out_channels), nn.LayerNorm(out_channels), nn.SiLU()
        )

    def forward(self, features: Tensor, positions: Tensor) -> tuple[Tensor, Tensor]:
        """Point features ``(B, N, C_in)`` at ``positions`` ``(B, N, 3)``.

        Returns
        -------
        features : (B, N, C_out) tensor
        volume : (B, C_out, R, R, R) tensor
            The voxel branch's output.
        """
        volume = self.voxel(voxelize(features, positions, self.resolution))
        return devoxelize(volume, positions) + self.point(features), volume


class PointVoxelStack(nn.Module):
    """PVConv layers applied to token features (the paper's denoiser/connectivity option),
    added residually to a ``width``-channel token stream."""

    def __init__(self, *, width: int, layers: tuple[tuple[int, int], ...]) -> None:
        super().__init__()
        self.convs = nn.ModuleList()
        channels = width
        for resolution, out in layers:
            self.convs.append(
                PVConv(in_channels=channels, out_channels=out, resolution=resolution)
            )
            channels = out
        self.out = nn.Linear(channels, width) if layers else nn.Identity()

    def forward(self, h: Tensor, positions: Tensor) -> Tensor:
        """``h`` ``(B, N, W)`` plus the stack's output at ``positions`` ``(B, N, 3)``."""
        if not len(self.convs):
            return h
        f = h
        for conv in self.convs:
            f, _ = conv(f, positions)
        return h + self.out(f)


class PVCNNEncoder(nn.Module):
    """The point-cloud encoder: a per-point stem, then one PVConv per resolution.

    Parameters
    ----------
    in_channels : int
        3 (positions) or 6 (positions and normals).
    stem : int
    resolutions, channels : tuple of int
    """

    def __init__(
        self, *, in_channels: int, stem: int, resolutions: tuple[int, ...],
        channels: tuple[int, ...],
    ) -> None:
        super().__init__()
        if len(resolutions) != len(channels):
            raise ValueError("resolutions and channels must have the same length")
        self.stem = nn.Sequential(nn.Linear(in_channels, stem), nn.LayerNorm(stem), nn.SiLU())
        self.layers = nn.ModuleList()
        c = stem
        for r, out in zip(resolutions, channels, strict=True):
            self.layers.append(PVConv(in_channels=c, out_channels=out, resolution=r))
            c = out
        self.channels = tuple(channels)

    def forward(self, points: Tensor) -> list[Tensor]:
        """Feature volumes of a point cloud.

        Parameters
        ----------
        points : (B, P, 3 or 6) tensor
            Positions in [-1, 1] (then normals, if the encoder reads them).

        Returns
        -------
        list of (B, C_r, R_r, R_r, R_r) tensors
        """
        positions = points[..., :3]
        h = self.stem(points)  # (B, P, stem)
        volumes = []
        for layer in self.layers:
            h, volume = layer(h, positions)
            volumes.append(volume)
        return volumes
