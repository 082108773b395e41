"""The three SpaceMesh networks together, and how their losses combine.

:class:`SpaceMeshModel` holds the PVCNN encoder, the vertex denoiser and the connectivity
network. Its ``forward`` computes the losses of one training step of either kind
(so that DistributedDataParallel wraps one module):

``mode="diffusion"``
    ``epsilon_weight * L_eps + mask_weight * L_mask`` on padded vertex tokens.
``mode="connectivity"``
    ``edge_weight * L_edge + permutation_weight * L_perm`` on ground-truth vertices,
    where ``L_edge`` is Eq. 3 averaged over the vertex pairs of each mesh (the mean a
    binary cross-entropy takes; the paper multiplies it by 200) and ``L_perm`` is Eq. 5.

:class:`TorchBackend` exposes the networks with numpy inputs and outputs, the interface
the runtime pipeline drives; the exported ONNX graphs implement the same interface.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from spacemesh.connectivity import Connectivity
from spacemesh.decode import DecodeOptions
from spacemesh.nn.config import ModelConfig, get_config
from spacemesh.nn.connectivity_net import ConnectivityNet
from spacemesh.nn.denoiser import VertexDenoiser
from spacemesh.nn.diffusion import GaussianDiffusion, vertex_tokens
from spacemesh.nn.losses import PermutationReduction, edge_loss_dense
from spacemesh.nn.pvcnn import PVCNNEncoder
from spacemesh.permutation import SINKHORN_ITERS
from spacemesh.runtime.backend import ConnectivityOutputs


class SpaceMeshModel(nn.Module):
    """Encoder, denoiser and connectivity network of one configuration.

    Parameters
    ----------
    config : ModelConfig
    """

    def __init__(self, *, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        enc = config.encoder
        self.encoder = PVCNNEncoder(
            in_channels=6 if enc.normals else 3, stem=enc.stem,
            resolutions=enc.resolutions, channels=enc.channels,
        )
        features = sum(enc.channels)
        den = config.denoiser
        self.denoiser = VertexDenoiser(
            width=den.width, layers=den.layers, heads=den.heads, feature_channels=features,
            point_voxel=den.point_voxel, local_points=den.local_points,
            local_width=den.local_width, normals=enc.normals,
        )
        con = config.connectivity
        self.connectivity = ConnectivityNet(
            width=con.width, layers=con.layers, heads=con.heads, feature_channels=features,
            adjacency_dim=con.adjacency_dim, permutation_dim=con.permutation_dim,
            distance_bias=con.distance_bias, fourier=con.fourier,
            position_prior=con.position_prior, point_voxel=con.point_voxel,
            neighbours=con.neighbours, geometric_attention=con.geometric_attention,
        )
        self.reduction = PermutationReduction(con.reduction, dim=con.permutation_dim)
        self.diffusion = GaussianDiffusion(
            schedule=config.diffusion.schedule, timesteps=config.diffusion.timesteps
        )

    @property
    def decode_options(self) -> DecodeOptions:
        """How the decode reads this model's embeddings."""
        con = self.config.connectivity
        return DecodeOptions(
            distance=con.distance, n_space=con.n_space, reduction=con.reduction,
            reduction_params=self.reduction.numpy_params(),
        )

    def forward(
        self,
        mode: str,
        points: Tensor,
        positions: Tensor,
        valid: Tensor,
        adjacency: Tensor | None = None,
        table: NeighbourTable | None = None,
        generator: torch.Generator | None = None,
        volumes: list[Tensor] | None = None,
    ) -> dict[str, Tensor]:
        """The weighted loss of one training step and its parts.

        Parameters
        ----------
        mode : {"diffusion", "connectivity"}
        points : (B, P, 3 or 6) tensor
            Conditioning points (and normals).
        positions : (B, N, 3) tensor
            Ground-truth vertices, padded (``N = max_vertices`` for diffusion).
        valid : (B, N) bool tensor
            Real vertices (a prefix of each row).
        adjacency : (B, N, N) bool tensor
            Ground-truth edges (connectivity mode).
        table : NeighbourTable
            Ground-truth neighbourhoods over the flattened ``B * N`` vertices.
        generator : torch.Generator, optional
            Draws the diffusion timesteps and noise.
        volumes : list of tensors, optional
            The encoder's volumes of ``points``, already computed (a frozen encoder's,
            from a cache); the encoder is not run then.

        Returns
        -------
        dict of () tensors
            ``loss`` (weighted total) and its unweighted parts.
        """
        train = self.config.train
        if volumes is None:
            if mode == "connectivity" and not train.connectivity_trains_encoder:
                with torch.no_grad():
                    volumes = [v.detach() for v in self.encoder(points)]
            else:
                volumes = self.encoder(points)
        if mode == "diffusion":
            x0 = vertex_tokens(positions, valid)

            def denoiser(x_t: Tensor, t: Tensor, vols: list[Tensor]) -> Tensor:
                return self.denoiser(x_t, t, vols, points)

            parts = self.diffusion.training_losses(denoiser, x0, volumes, generator)
            loss = train.epsilon_weight * parts["epsilon"] + train.mask_weight * parts["mask"]
            return {"loss": loss, **parts}
        if mode != "connectivity":
            raise ValueError(f"unknown mode {mode!r}")
        if adjacency is None or table is None:
            raise ValueError("connectivity mode needs adjacency and a neighbour table")
        x, root, prev, nxt, tau = self.connectivity(positions, valid, volumes)
        edge = pairwise_edge_loss(x, tau, adjacency, valid, self.config)
        b, n, kp = root.shape
        perm, correct = padded_permutation_loss(
            table, root.reshape(b * n, kp), prev.reshape(b * n, kp), nxt.reshape(b * n, kp),
            self.reduction,
        )
        loss = train.edge_weight * edge + train.permutation_weight * perm
        return {
            "loss": loss, "edge": edge, "permutation": perm,
            "next_rows": correct.float() / max(table.rows, 1),
        }


def pairwise_edge_loss(
    x: Tensor, tau: Tensor, adjacency: Tensor, valid: Tensor, config: ModelConfig
) -> Tensor:
    """Eq. 3 per mesh, averaged over its vertex pairs, then over meshes.

    :func:`spacemesh.nn.losses.edge_loss_dense` normalises by the edge count ``E``;
    multiplying by ``E / P`` (``P`` unordered valid pairs) turns that into the mean over
    pairs that the paper's weight of 200 is set for.

    Parameters
    ----------
    x : (B, N, k) tensor
    tau : (1,) tensor
    adjacency : (B, N, N) bool tensor
    valid : (B, N) bool tensor
        A prefix of each row.
    config : ModelConfig

    Returns
    -------
    () tensor
    """
    con, train = config.connectivity, config.train
    counts = valid.sum(1).tolist()
    total = x.new_zeros(())
    for i, n in enumerate(counts):
        if n < 2:
            continue
        adj = adjacency[i : i + 1, :n, :n]
        per_edge = edge_loss_dense(
            x[i : i + 1, :n], tau, adj, None, con.distance, con.n_space,
            train.false_positive_weight, train.false_positive_margin,
        )
        n_edges = max(int(adj.sum()) // 2, 1)
        total = total + per_edge * (n_edges / (n * (n - 1) / 2))
    return total / max(len(counts), 1)


#: Degree buckets of :class:`NeighbourTable` (a last bucket takes the rest).
DEGREE_BUCKETS = (4, 5, 6, 7, 8, 10, 12, 16)

#: Floor of ``logit - row max`` in the exp-domain Sinkhorn (``exp(-60)`` is far above
#: float32's smallest normal, so no real entry underflows to zero).
EXP_FLOOR = -60.0


@dataclass(frozen=True)
class NeighbourBlock:
    """Ground-truth neighbourhoods of degrees up to ``D``, padded to ``D``.

    Attributes
    ----------
    vertices : (V,) long
        Centre vertices.
    neighbours : (V, D) long
        Sorted neighbours; padding slots repeat the centre.
    target : (V, D) long
        Local successor of each slot; padding slots point to themselves.
    mask : (V, D) bool
        Real slots.
    """

    vertices: Tensor
    neighbours: Tensor
    target: Tensor
    mask: Tensor

    def to(self, device: torch.device | str) -> NeighbourBlock:
        """The block on ``device``."""
        return NeighbourBlock(*(t.to(device) for t in (self.vertices, self.neighbours,
                                                         self.target, self.mask)))


@dataclass(frozen=True)
class NeighbourTable:
    """All ground-truth neighbourhoods (degree >= 2) of a graph, in a few padded blocks.

    Vertices are bucketed by degree (:data:`DEGREE_BUCKETS`) so that padding stays small.
    """

    blocks: tuple[NeighbourBlock, ...]

    @classmethod
    def from_connectivity(
        cls, connectivity: Connectivity, buckets: tuple[int, ...] = DEGREE_BUCKETS
    ) -> NeighbourTable:
        """The table of every vertex of degree >= 2 of ``connectivity``."""
        degree = connectivity.degree
        local = connectivity.local_successor()
        blocks = []
        low = 2
        for high in (*buckets, max(int(degree.max(initial=0)), buckets[-1])):
            vertices = np.flatnonzero((degree >= low) & (degree <= high))
            low = high + 1
            if vertices.size == 0:
                continue
            d = int(degree[vertices].max())
            slot = np.arange(d)[None, :]  # (1, D)
            mask = slot < degree[vertices][:, None]  # (V, D)
            index = np.where(mask, connectivity.offsets[vertices][:, None] + slot, 0)
            neighbours = np.where(mask, connectivity.neighbours[index], vertices[:, None])
            target = np.where(mask, local[index], slot)
            blocks.append(NeighbourBlock(
                *(torch.as_tensor(a) for a in (vertices, neighbours, target, mask))
            ))
        return cls(tuple(blocks))

    @property
    def rows(self) -> int:
        """Number of supervised ``next`` relations."""
        return int(sum(int(b.mask.sum()) for b in self.blocks))

    def to(self, device: torch.device | str) -> NeighbourTable:
        """The table on ``device``."""
        return NeighbourTable(tuple(b.to(device) for b in self.blocks))


def block_log_phi_bar(
    block: NeighbourBlock, root: Tensor, prev: Tensor, nxt: Tensor,
    reduction: PermutationReduction, n_iters: int = SINKHORN_ITERS,
) -> Tensor:
    """``log Phi_bar`` ``(V, D, D)`` of a padded block (padding entries are meaningless).

    Each ``d x d`` neighbourhood sits in the top-left of a ``D x D`` matrix whose padding
    block is the identity and whose cross blocks are zero, so Sinkhorn normalises every
    neighbourhood exactly as it would alone. Sinkhorn runs in the exp domain after
    subtracting each row's maximum (the same fixed point as the log-domain iteration of
    :func:`spacemesh.nn.losses.log_sinkhorn`, at a fraction of the cost).
    """
    logits = reduction(root[block.vertices], prev[block.neighbours], nxt[block.neighbours])
    logits = logits.float()  # (V, D, D)
    d = logits.shape[-1]
    eye = torch.eye(d, dtype=torch.bool, device=logits.device)
    real = block.mask[:, :, None] & block.mask[:, None, :]  # (V, D, D)
    live = real & ~eye  # supervised entries (off-diagonal, inside the neighbourhood)
    masked = logits.masked_fill(~live, float("-inf"))
    top = masked.amax(-1, keepdim=True).masked_fill(~block.mask[..., None], 0.0)  # (V, D, 1)
    p = torch.exp((masked - top).clamp_min(EXP_FLOOR)) * live
    p = p + (eye & ~real).to(p.dtype)  # the identity on padding
    for _ in range(n_iters):
        p = p / p.sum(-1, keepdim=True)
        p = p / p.sum(-2, keepdim=True)
    return torch.log(p.clamp_min(torch.finfo(p.dtype).tiny))


def padded_permutation_loss(
    table: NeighbourTable,
    root: Tensor,
    prev: Tensor,
    nxt: Tensor,
    reduction: PermutationReduction,
    n_iters: int = SINKHORN_ITERS,
) -> tuple[Tensor, Tensor]:
    """Eq. 5 on padded degree blocks (equals :func:`spacemesh.nn.losses.permutation_loss`).

    Parameters
    ----------
    table : NeighbourTable
    root, prev, nxt : (N, kp) tensors
    reduction : PermutationReduction
    n_iters : int

    Returns
    -------
    loss : () tensor
        Mean of ``-log Phi_bar^i[j, k]`` over ground-truth ``next`` relations.
    correct : () long tensor
        Rows whose target is the row maximum.
    """
    total = root.new_zeros((), dtype=torch.float32)
    correct = torch.zeros((), dtype=torch.long, device=root.device)
    count = 0
    for block in table.blocks:
        log_phi_bar = block_log_phi_bar(block, root, prev, nxt, reduction, n_iters)
        picked = log_phi_bar.gather(-1, block.target[..., None]).squeeze(-1)  # (V, D)
        total = total - (picked * block.mask).sum()
        correct = correct + ((log_phi_bar.argmax(-1) == block.target) & block.mask).sum()
        count += int(block.mask.sum())
    return total / max(count, 1), correct


class TorchBackend:
    """The torch networks behind the runtime's backend interface (numpy in, numpy out).

    Parameters
    ----------
    model : SpaceMeshModel
    """

    def __init__(self, model: SpaceMeshModel) -> None:
        self.model = model.eval()
        self.device = next(model.parameters()).device

    def _tensor(self, a: np.ndarray) -> Tensor:
        return torch.as_tensor(a, device=self.device)

    @torch.no_grad()
    def encode(self, points: np.ndarray) -> list[np.ndarray]:
        """Feature volumes of ``points`` ``(B, P, 3 or 6)`` float32."""
        return [v.float().cpu().numpy() for v in self.model.encoder(self._tensor(points))]

    @torch.no_grad()
    def denoise(self, x_t: np.ndarray, t: np.ndarray, volumes: list[np.ndarray],
                points: np.ndarray | None = None) -> np.ndarray:
        """Predicted noise ``(B, N, 4)`` of tokens ``x_t`` at timesteps ``t`` ``(B,)``
        (``points``: the encoder's input, read by a local-point denoiser)."""
        vols = [self._tensor(v) for v in volumes]
        cloud = None if points is None else self._tensor(np.asarray(points, np.float32))
        eps = self.model.denoiser(self._tensor(x_t), self._tensor(t), vols, cloud)
        return eps.float().cpu().numpy()

    @torch.no_grad()
    def connect(
        self, vertices: np.ndarray, valid: np.ndarray, volumes: list[np.ndarray]
    ) -> ConnectivityOutputs:
        """Embeddings of ``vertices`` ``(B, N, 3)`` with ``valid`` ``(B, N)`` bool."""
        vols = [self._tensor(v) for v in volumes]
        x, root, prev, nxt, tau = self.model.connectivity(
            self._tensor(vertices), self._tensor(valid), vols
        )
        out = [a.float().cpu().numpy() for a in (x, root, prev, nxt)]
        return ConnectivityOutputs(*out, tau=float(tau.reshape(-1)[0]))


def model_from_config(config: ModelConfig | str | dict, device: Any = None) -> SpaceMeshModel:
    """Build the three networks of a configuration (the only factory).

    Parameters
    ----------
    config : ModelConfig, str or dict
        A configuration, a configuration name, or a dict from :meth:`ModelConfig.to_dict`.
    device : torch device, optional

    Returns
    -------
    SpaceMeshModel
    """
    if isinstance(config, str):
        config = get_config(config)
    elif isinstance(config, dict):
        config = ModelConfig.from_dict(config)
    model = SpaceMeshModel(config=config)
    return model.to(device) if device is not None else model
