"""The SpaceMesh losses in torch (paper Eq. 3 and Eq. 5), shared by fitting and training.

Conventions match the numpy decode exactly (a test holds them together):

- distances come from the same augmented operands as :mod:`spacemesh.spacetime`;
- an edge is ``d < tau``; the edge loss is the logistic loss on ``tau - d`` for ground
  truth edges and on ``d - tau`` for the other pairs, the latter weighted by
  ``lambda = 4 E / V^2``;
- ``Phi`` logits use the reductions of :mod:`spacemesh.permutation`, the diagonal is
  excluded, and Sinkhorn runs in the log domain for the same number of iterations;
- the permutation loss is ``-log Phi_bar[a, successor(a)]`` over all ground-truth
  ``next`` relations, with rows and columns indexed by sorted neighbour slots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from spacemesh.connectivity import Connectivity
from spacemesh.permutation import SINKHORN_ITERS, group_by_degree
from spacemesh.spacetime import Distance, signature


def distance_operands(
    x: Tensor, distance: Distance = "spacetime", n_space: int | None = None
) -> tuple[Tensor, Tensor]:
    """Operands with ``d(x_i, x_j) = a_i . b_j`` (torch twin of the numpy function).

    Parameters
    ----------
    x : (..., N, k) tensor
    distance : {"spacetime", "euclidean", "dot"}
    n_space : int, optional

    Returns
    -------
    a, b : (..., N, k + 2) tensors (``k`` for ``dot``)
    """
    if distance == "dot":
        return x, -x
    g = torch.as_tensor(signature(x.shape[-1], n_space, distance), dtype=x.dtype, device=x.device)
    q = (x * x * g).sum(-1, keepdim=True)
    one = torch.ones_like(q)
    return torch.cat([x * g, q, one], -1), torch.cat([-2.0 * x, one, q], -1)


def pair_distance(
    x: Tensor, i: Tensor, j: Tensor, distance: Distance = "spacetime", n_space: int | None = None
) -> Tensor:
    """Distances of the pairs ``(i[m], j[m])``.

    Parameters
    ----------
    x : (N, k) tensor
    i, j : (M,) long tensors

    Returns
    -------
    (M,) tensor
    """
    a, b = distance_operands(x, distance, n_space)
    return (a[i] * b[j]).sum(-1)


def dense_distance(
    x: Tensor, distance: Distance = "spacetime", n_space: int | None = None
) -> Tensor:
    """All pairwise distances ``(..., N, N)`` of ``x`` ``(..., N, k)`` (one matrix product)."""
    a, b = distance_operands(x, distance, n_space)
    return a @ b.transpose(-1, -2)


def edge_weight(n_edges: Tensor | float, n_vertices: Tensor | float) -> Tensor | float:
    """``lambda = 4 E / V^2``, the weight of the non-edge term (paper Supplement A)."""
    return 4.0 * n_edges / (n_vertices * n_vertices)


def edge_loss_dense(
    x: Tensor,
    tau: Tensor,
    adjacency: Tensor,
    valid: Tensor | None = None,
    distance: Distance = "spacetime",
    n_space: int | None = None,
    false_positive_weight: float | None = None,
    false_positive_margin: float = 0.0,
) -> Tensor:
    """Eq. 3 over every pair of valid vertices, averaged over the batch.

    Parameters
    ----------
    x : (B, N, k) tensor
        Adjacency embeddings.
    tau : () or (B,) tensor
        Threshold(s).
    adjacency : (B, N, N) bool tensor
        Ground-truth edges (symmetric, no diagonal).
    valid : (B, N) bool tensor, optional
        Real (non-padding) vertices.
    distance, n_space
        See :func:`distance_operands`.
    false_positive_weight : float, optional
        Weight of the non-edges currently below the threshold (instead of ``lambda``),
        scaled down so that together they weigh at most as much as the edges; None
        keeps the paper's loss exactly.
    false_positive_margin : float
        Non-edges count as false positives up to ``d < tau + margin``: a hysteresis
        that keeps their weight until they are clearly out (without it they sit on the
        threshold, flipping in and out).

    Returns
    -------
    () tensor
        Per mesh ``(sum_pos softplus(d - tau) + lambda sum_neg softplus(tau - d)) / E``,
        over unordered pairs, averaged over meshes.
    """
    b, n, _ = x.shape
    if valid is None:
        valid = torch.ones(b, n, dtype=torch.bool, device=x.device)
    d = dense_distance(x, distance, n_space)  # (B, N, N)
    logit = tau.reshape(-1, 1, 1) - d  # > 0 means edge
    pair = valid[:, :, None] & valid[:, None, :]
    pair = torch.triu(pair, diagonal=1)
    pos = adjacency & pair
    neg = pair & ~adjacency
    n_edges = pos.sum((1, 2)).clamp_min(1).to(x.dtype)
    n_vertices = valid.sum(1).clamp_min(1).to(x.dtype)
    lam = edge_weight(n_edges, n_vertices)
    pos_term = (F.softplus(-logit) * pos).sum((1, 2))
    neg_weight = lam.reshape(-1, 1, 1) * neg
    if false_positive_weight is not None:
        false_pos = neg & (logit > -false_positive_margin)
        # together the false positives weigh at most as much as the edges
        share = (n_edges / false_pos.sum((1, 2)).clamp_min(1)).clamp(max=1.0)
        fp_weight = (false_positive_weight * share).reshape(-1, 1, 1).detach()
        neg_weight = torch.where(false_pos, torch.maximum(fp_weight, neg_weight), neg_weight)
    neg_term = (F.softplus(logit) * neg_weight).sum((1, 2))
    return ((pos_term + neg_term) / n_edges).mean()


def edge_loss_pairs(
    x: Tensor,
    tau: Tensor,
    positives: Tensor,
    negatives: Tensor,
    negative_weights: Tensor,
    lam: float,
    distance: Distance = "spacetime",
    n_space: int | None = None,
    false_positive_weight: float | None = None,
    false_positive_margin: float = 0.0,
) -> Tensor:
    """Eq. 3 on explicit pairs: all positives, a weighted subset of negatives.

    Parameters
    ----------
    x : (N, k) tensor
    tau : () tensor
    positives : (E, 2) long tensor
    negatives : (M, 2) long tensor
    negative_weights : (M,) tensor
        How many negatives each sampled one stands for (1 for mined hard negatives).
    lam : float
        ``4 E / V^2``.
    false_positive_weight : float, optional
        See :func:`edge_loss_dense`; applies to the negatives of weight 1 (mined ones).
    false_positive_margin : float
        See :func:`edge_loss_dense`.

    Returns
    -------
    () tensor
        Unbiased estimate of the dense loss of :func:`edge_loss_dense`.
    """
    a, b = distance_operands(x, distance, n_space)
    d_pos = (a[positives[:, 0]] * b[positives[:, 1]]).sum(-1)
    d_neg = (a[negatives[:, 0]] * b[negatives[:, 1]]).sum(-1)
    pos_term = F.softplus(d_pos - tau).sum()
    weights = lam * negative_weights
    if false_positive_weight is not None:
        # only pairs that stand for themselves: sampled stand-ins stay unbiased
        hard = (d_neg < tau + false_positive_margin) & (negative_weights <= 1)
        share = min(1.0, len(positives) / max(int(hard.sum()), 1))
        fp_weight = torch.full_like(weights, false_positive_weight * share)
        weights = torch.where(hard, torch.maximum(fp_weight, weights), weights)
    neg_term = (F.softplus(tau - d_neg) * weights).sum()
    return (pos_term + neg_term) / max(len(positives), 1)


class PermutationReduction(nn.Module):
    """The reduction F of Eq. 6 and its ablation alternatives, as a torch module.

    Parameters
    ----------
    kind : {"product", "sum", "max", "concat"}
    dim : int
        Permutation embedding size ``kp``.
    hidden : int
        Hidden width of the ``concat`` MLP.
    """

    def __init__(self, kind: str = "product", *, dim: int = 6, hidden: int = 32) -> None:
        super().__init__()
        self.kind = kind
        if kind == "concat":
            self.w1 = nn.Parameter(torch.randn(3 * dim, hidden) / np.sqrt(3 * dim))
            self.b1 = nn.Parameter(torch.zeros(hidden))
            self.w2 = nn.Parameter(torch.randn(hidden) / np.sqrt(hidden))

    def forward(self, root: Tensor, prev: Tensor, nxt: Tensor) -> Tensor:
        """Logits ``(B, d, d)`` from root ``(B, kp)``, prev and next ``(B, d, kp)``."""
        if self.kind == "product":
            return torch.einsum("bak,bk,bck->bac", prev, root, nxt)
        if self.kind == "sum":
            return root.sum(-1)[:, None, None] + prev.sum(-1)[:, :, None] + nxt.sum(-1)[:, None, :]
        if self.kind == "max":
            stacked = torch.maximum(prev[:, :, None, :], nxt[:, None, :, :])
            return torch.maximum(stacked, root[:, None, None, :]).sum(-1)
        if self.kind == "concat":
            kp = root.shape[-1]
            hidden = (
                (root @ self.w1[:kp])[:, None, None, :]
                + (prev @ self.w1[kp : 2 * kp])[:, :, None, :]
                + (nxt @ self.w1[2 * kp :])[:, None, :, :]
                + self.b1
            )
            return torch.relu(hidden) @ self.w2
        raise ValueError(f"unknown reduction {self.kind!r}")

    def numpy_params(self) -> dict[str, np.ndarray] | None:
        """Weights for :func:`spacemesh.permutation.reduction_logits` (concat only)."""
        if self.kind != "concat":
            return None
        return {k: getattr(self, k).detach().cpu().double().numpy() for k in ("w1", "b1", "w2")}


def log_sinkhorn(logits: Tensor, n_iters: int = SINKHORN_ITERS) -> Tensor:
    """Log-domain Sinkhorn over the last two dims (torch twin of the numpy function)."""
    for _ in range(n_iters):
        logits = logits - torch.logsumexp(logits, dim=-1, keepdim=True)
        logits = logits - torch.logsumexp(logits, dim=-2, keepdim=True)
    return logits


def masked_diagonal(logits: Tensor) -> Tensor:
    """``logits`` ``(B, d, d)`` with the diagonal at ``-inf`` (when ``d >= 2``)."""
    d = logits.shape[-1]
    if d < 2:
        return logits
    eye = torch.eye(d, dtype=torch.bool, device=logits.device)
    return logits.masked_fill(eye, float("-inf"))


@dataclass(frozen=True)
class DegreeGroup:
    """Ground-truth neighbourhoods of one degree, as index tensors.

    Attributes
    ----------
    degree : int
    vertices : (B,) long
        Centre vertices.
    neighbours : (B, d) long
        Their sorted neighbours.
    target : (B, d) long
        Local successor of each row (the supervised column).
    """

    degree: int
    vertices: Tensor
    neighbours: Tensor
    target: Tensor


def degree_groups(
    connectivity: Connectivity, device: torch.device | str = "cpu"
) -> list[DegreeGroup]:
    """Group a ground-truth connectivity by vertex degree (degrees >= 2 only).

    Parameters
    ----------
    connectivity : Connectivity
        Usually from :func:`spacemesh.encode.encode_connectivity` (a batch of meshes can
        be concatenated into one connectivity with offset indices).
    device : torch device

    Returns
    -------
    list of DegreeGroup
    """
    offsets = connectivity.offsets
    local = connectivity.local_successor()
    groups = []
    for degree, vertices in sorted(group_by_degree(offsets).items()):
        if degree < 2:
            continue
        slots = offsets[vertices][:, None] + np.arange(degree)[None, :]
        groups.append(
            DegreeGroup(
                degree=degree,
                vertices=torch.as_tensor(vertices, device=device),
                neighbours=torch.as_tensor(connectivity.neighbours[slots], device=device),
                target=torch.as_tensor(local[slots], device=device),
            )
        )
    return groups


def group_log_phi_bar(
    group: DegreeGroup,
    root: Tensor,
    prev: Tensor,
    nxt: Tensor,
    reduction: PermutationReduction,
    n_iters: int = SINKHORN_ITERS,
) -> Tensor:
    """``log Phi_bar`` ``(B, d, d)`` of one degree group (embeddings ``(N, kp)``)."""
    logits = reduction(root[group.vertices], prev[group.neighbours], nxt[group.neighbours])
    return log_sinkhorn(masked_diagonal(logits), n_iters)


def permutation_loss(
    groups: list[DegreeGroup],
    root: Tensor,
    prev: Tensor,
    nxt: Tensor,
    reduction: PermutationReduction,
    n_iters: int = SINKHORN_ITERS,
) -> tuple[Tensor, Tensor]:
    """Eq. 5: mean of ``-log Phi_bar^i[j, k]`` over ground-truth ``next`` relations.

    Parameters
    ----------
    groups : list of DegreeGroup
    root, prev, nxt : (N, kp) tensors
    reduction : PermutationReduction
    n_iters : int

    Returns
    -------
    loss : () tensor
    correct : () long tensor
        How many rows have their target as the row maximum (a cheap accuracy).
    """
    total = root.new_zeros(())
    correct = torch.zeros((), dtype=torch.long, device=root.device)
    count = 0
    for group in groups:
        log_phi_bar = group_log_phi_bar(group, root, prev, nxt, reduction, n_iters)
        picked = log_phi_bar.gather(-1, group.target[..., None]).squeeze(-1)  # (B, d)
        total = total - picked.sum()
        correct = correct + (log_phi_bar.argmax(-1) == group.target).sum()
        count += picked.numel()
    return total / max(count, 1), correct
