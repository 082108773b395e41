"""Residual self-attention blocks shared by the denoiser and the connectivity network.

Point-E's layout: pre-norm blocks ``x + attn(ln(x))`` then ``x + mlp(ln(x))`` with a 4x
GELU MLP. There is no positional embedding anywhere: tokens are a set. Attention takes
an optional additive bias ``(B, H or 1, N, N)``: key padding and, in the connectivity
network, a learned distance prior. With ``geometry=True`` (the connectivity network)
each attention layer also adds a projection of the mean and covariance of the offsets
to the vertices each head attends to (:func:`spacemesh.nn.geometry.offset_moments`).
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from spacemesh.nn.geometry import MOMENT_CHANNELS, offset_moments

#: Added to the logits of masked keys (finite, so an all-masked row stays finite).
MASKED = -1e9


def init_linear(layer: nn.Linear, scale: float) -> None:
    """Normal weights with standard deviation ``scale``, zero bias (as in Point-E)."""
    nn.init.normal_(layer.weight, std=scale)
    if layer.bias is not None:
        nn.init.zeros_(layer.bias)


class MultiheadSelfAttention(nn.Module):
    """Self-attention over a set of tokens.

    Parameters
    ----------
    width, heads : int
    init_scale : float
    geometry : bool
        Add a projection of each head's offset moments (needs ``positions``).
    """

    def __init__(
        self, *, width: int, heads: int, init_scale: float = 0.25, geometry: bool = False
    ) -> None:
        super().__init__()
        if width % heads:
            raise ValueError("width must be a multiple of heads")
        self.heads = heads
        self.qkv = nn.Linear(width, 3 * width)
        self.proj = nn.Linear(width, width)
        init_linear(self.qkv, init_scale / math.sqrt(width))
        init_linear(self.proj, init_scale / math.sqrt(width))
        self.geometry = nn.Linear(MOMENT_CHANNELS * heads, width) if geometry else None
        if self.geometry is not None:
            init_linear(self.geometry, init_scale / math.sqrt(MOMENT_CHANNELS * heads))

    def forward(
        self, x: Tensor, bias: Tensor | None = None, positions: Tensor | None = None
    ) -> Tensor:
        """``x`` ``(B, N, W)``, ``bias`` broadcastable to ``(B, H, N, N)``, ``positions``
        ``(B, N, 3)`` (read when ``geometry``)."""
        b, n, w = x.shape
        qkv = self.qkv(x).reshape(b, n, 3, self.heads, w // self.heads)
        q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # (B, H, N, D) each
        scores = (q @ k.transpose(-1, -2)).float() * (1.0 / math.sqrt(w // self.heads))
        if bias is not None:
            scores = scores + bias  # (B, H, N, N)
        weights = torch.softmax(scores, dim=-1).to(v.dtype)
        out = weights @ v  # (B, H, N, D)
        out = self.proj(out.transpose(1, 2).reshape(b, n, w))
        if self.geometry is None:
            return out
        if positions is None:
            raise ValueError("geometric attention needs the token positions")
        return out + self.geometry(offset_moments(weights.float(), positions).to(out.dtype))


class MLP(nn.Module):
    """Two linear layers with GELU, 4x wide."""

    def __init__(self, *, width: int, init_scale: float = 0.25) -> None:
        super().__init__()
        self.fc = nn.Linear(width, 4 * width)
        self.proj = nn.Linear(4 * width, width)
        self.act = nn.GELU()
        init_linear(self.fc, init_scale / math.sqrt(width))
        init_linear(self.proj, init_scale / math.sqrt(4 * width))

    def forward(self, x: Tensor) -> Tensor:
        """``(B, N, W)`` to ``(B, N, W)``."""
        return self.proj(self.act(self.fc(x)))


class ResidualAttentionBlock(nn.Module):
    """``x + attn(ln(x))``, then ``x + mlp(ln(x))``."""

    def __init__(
        self, *, width: int, heads: int, init_scale: float = 0.25, geometry: bool = False
    ) -> None:
        super().__init__()
        self.ln_1 = nn.LayerNorm(width)
        self.attn = MultiheadSelfAttention(width=width, heads=heads, init_scale=init_scale,
                                           geometry=geometry)
        self.ln_2 = nn.LayerNorm(width)
        self.mlp = MLP(width=width, init_scale=init_scale)

    def forward(
        self, x: Tensor, bias: Tensor | None = None, positions: Tensor | None = None
    ) -> Tensor:
        """``(B, N, W)`` to ``(B, N, W)``."""
        x = x + self.attn(self.ln_1(x), bias, positions)
        return x + self.mlp(self.ln_2(x))


class Transformer(nn.Module):
    """A stack of :class:`ResidualAttentionBlock`.

    Parameters
    ----------
    width, layers, heads : int
    init_scale : float
        Initial weights have standard deviation ``init_scale / sqrt(fan_in)`` (Point-E).
    geometry : bool
        Geometric attention (see :class:`MultiheadSelfAttention`).
    """

    def __init__(
        self, *, width: int, layers: int, heads: int, init_scale: float = 0.25,
        geometry: bool = False,
    ) -> None:
        super().__init__()
        self.width = width
        self.heads = heads
        self.blocks = nn.ModuleList(
            ResidualAttentionBlock(width=width, heads=heads, init_scale=init_scale,
                                   geometry=geometry)
            for _ in range(layers)
        )

    def forward(
        self, x: Tensor, bias: Tensor | None = None, positions: Tensor | None = None
    ) -> Tensor:
        """``(B, N, W)`` to ``(B, N, W)``; ``bias`` and ``positions`` are shared by all
        blocks."""
        for block in self.blocks:
            x = block(x, bias, positions)
        return x


def key_padding_bias(valid: Tensor) -> Tensor:
    """Additive attention bias ``(B, 1, 1, N)``: 0 for real keys, :data:`MASKED` for padding."""
    zero = torch.zeros((), dtype=torch.float32, device=valid.device)
    masked = torch.full((), MASKED, dtype=torch.float32, device=valid.device)
    return torch.where(valid, zero, masked)[:, None, None, :]


def timestep_embedding(t: Tensor, dim: int, max_period: float = 10000.0) -> Tensor:
    """Sinusoidal embedding ``(B, dim)`` of timesteps ``t`` ``(B,)`` (int or float)."""
    half = dim // 2
    freqs = torch.exp(
        -math.log(max_period) * torch.arange(half, dtype=torch.float32, device=t.device) / half
    )
    args = t.float()[:, None] * freqs[None]
    emb = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)
    if dim % 2:
        emb = torch.cat([emb, torch.zeros_like(emb[:, :1])], dim=-1)
    return emb
