"""The autodecoder of the collection fit (paper Supplement B).

One latent code per mesh, repeated over ``N`` vertex tokens, plus a learnable
positional embedding shared by all meshes, through a transformer encoder; a linear head
gives each token its position, a mask channel (+1 a vertex, -1 padding) and the
SpaceMesh embeddings ``x``, ``y_root``, ``y_prev``, ``y_next``. The edge threshold
``tau`` is one learned scalar shared by the collection.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from spacemesh.fitting.single import POSITIONS_TAU
from spacemesh.nn.losses import PermutationReduction


@dataclass(frozen=True)
class DecoderShape:
    """Sizes of :class:`CollectionDecoder` (made by
    :meth:`spacemesh.fitting.collection_config.CollectionConfig.shape`, whose fields hold
    the defaults).

    Attributes
    ----------
    n_meshes, n_tokens : int
        Latent codes and vertex tokens (the largest mesh's vertex count).
    latent_dim : int
        512 in the paper.
    width, layers, heads, feedforward : int
        The transformer.
    adjacency_dim, permutation_dim : int
        16 and 6, as in single-mesh fitting.
    reduction : str
        The permutation reduction (``product``).
    position_skip : bool
        Add the predicted positions (not differentiated), times a learned per-mesh
        scale, to the first three space coordinates of ``x``: adjacency starts from
        spatial proximity, as ``spacemesh fit --init positions`` does.
    """

    n_meshes: int
    n_tokens: int
    latent_dim: int
    width: int
    layers: int
    heads: int
    feedforward: int
    adjacency_dim: int
    permutation_dim: int
    reduction: str
    position_skip: bool


@dataclass
class DecodedTokens:
    """The decoder's outputs for a batch of meshes (``B`` meshes, ``N`` tokens)."""

    positions: Tensor  # (B, N, 3)
    mask: Tensor  # (B, N): > 0 for a vertex
    x: Tensor  # (B, N, k) adjacency embeddings
    root: Tensor  # (B, N, kp)
    prev: Tensor  # (B, N, kp)
    next: Tensor  # (B, N, kp)
    tau: Tensor  # ()


class CollectionDecoder(nn.Module):
    """Latent code per mesh -> ``N`` vertex tokens (see the module docstring).

    Parameters
    ----------
    shape : DecoderShape
    latent_std : float
        Standard deviation of the initial latent codes.
    embedding_scale : float
        Multiplies the head's embedding outputs, so that Adam's steps on the head move
        them as far as free embeddings move in single-mesh fitting.
    """

    def __init__(
        self, shape: DecoderShape, embedding_scale: float = 1.0, latent_std: float = 1.0
    ) -> None:
        super().__init__()
        self.shape = shape
        self.embedding_scale = embedding_scale
        self.latents = nn.Embedding(shape.n_meshes, shape.latent_dim)
        nn.init.normal_(self.latents.weight, std=latent_std)
        self.project = nn.Linear(shape.latent_dim, shape.width)
        self.positional = nn.Parameter(torch.randn(shape.n_tokens, shape.width))
        layer = nn.TransformerEncoderLayer(
            shape.width,
            shape.heads,
            shape.feedforward,
            dropout=0.0,
            batch_first=True,
            norm_first=True,
        )
        self.transformer = nn.TransformerEncoder(
            layer, shape.layers, norm=nn.LayerNorm(shape.width), enable_nested_tensor=False
        )
        self.n_out = 4 + shape.adjacency_dim + 3 * shape.permutation_dim
        self.head = nn.Linear(shape.width, self.n_out)
        # log of each mesh's position scale (about 1 / its mean edge length)
        self.log_scale = nn.Parameter(torch.zeros(shape.n_meshes))
        # with the skip, neighbours start about one edge apart: d ~ 1 < tau
        self.tau = nn.Parameter(torch.full((), POSITIONS_TAU if shape.position_skip else 0.0))
        self.reduction = PermutationReduction(shape.reduction, dim=shape.permutation_dim)

    def forward(self, meshes: Tensor) -> DecodedTokens:
        """Decode the meshes of indices ``meshes`` ``(B,)``."""
        h = self.project(self.latents(meshes))[:, None, :] + self.positional  # (B, N, W)
        out = self.head(self.transformer(h))  # (B, N, 4 + k + 3 kp)
        k, kp = self.shape.adjacency_dim, self.shape.permutation_dim
        emb = out[..., 4:] * self.embedding_scale
        if self.shape.position_skip:
            scale = self.log_scale[meshes].exp()[:, None, None]  # (B, 1, 1)
            skip = torch.zeros_like(emb)
            skip[..., :3] = out[..., :3].detach() * scale
            emb = emb + skip
        return DecodedTokens(
            positions=out[..., :3],
            mask=out[..., 3],
            x=emb[..., :k],
            root=emb[..., k : k + kp],
            prev=emb[..., k + kp : k + 2 * kp],
            next=emb[..., k + 2 * kp :],
            tau=self.tau,
        )
