"""The edge loss of a batch of decoded meshes on sampled pairs (Eq. 3).

Single-mesh fitting's sparse mode (:func:`spacemesh.nn.losses.edge_loss_pairs`), per
mesh: every edge; the non-edges currently within ``margin`` of the threshold, mined on
all pairs every step from the distance matrix that also gives the step's cheap edge F1
(all of those within ``false_positive_margin``, which get the false-positive weight, and
a subset of the others); and uniformly sampled non-edges that stand in for the rest. On
a loaded CPU this is several times cheaper than the dense loss over all ``N^2`` pairs of
every mesh, and an unbiased estimate of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from spacemesh.nn.losses import dense_distance, edge_loss_pairs, edge_weight


@dataclass(frozen=True)
class PairSampling:
    """How many non-edges each step uses, per edge of a mesh."""

    margin: float = 6.0  # mined: non-edges with d < tau + margin
    max_hard: int = 8  # at most this many mined non-edges per edge (a random subset)
    random_negatives: int = 4  # uniformly sampled non-edges per edge


@dataclass
class EdgeLossResult:
    """The batch's edge loss and its cheap F1 counts (before the step)."""

    loss: Tensor  # ()
    true_positives: int
    predicted: int
    edges: int


def _subset(pairs: Tensor, cap: int, generator: torch.Generator) -> tuple[Tensor, float]:
    """At most ``cap`` random rows of ``pairs`` and how many rows each stands for."""
    if len(pairs) <= cap:
        return pairs, 1.0
    keep = torch.randperm(len(pairs), generator=generator)[:cap].to(pairs.device)
    return pairs[keep], len(pairs) / cap


def sampled_edge_loss(
    x: Tensor,
    tau: Tensor,
    edges: list[Tensor],
    n_vertices: list[int],
    sampling: PairSampling,
    generator: torch.Generator,
    distance: str = "spacetime",
    n_space: int | None = None,
    false_positive_weight: float | None = 1.0,
    false_positive_margin: float = 0.5,
) -> EdgeLossResult:
    """Mean over the meshes of the sampled Eq. 3 loss.

    Parameters
    ----------
    x : (B, N, k) tensor
        Adjacency embeddings of the batch's tokens.
    tau : () tensor
    edges : list of (E_b, 2) long tensors
        Each mesh's edges (``i < j``).
    n_vertices : list of int
        Each mesh's vertex count (its first tokens).
    sampling : PairSampling
    generator : torch.Generator
    distance, n_space, false_positive_weight, false_positive_margin
        As :func:`spacemesh.nn.losses.edge_loss_pairs`.

    Returns
    -------
    EdgeLossResult
    """
    with torch.no_grad():
        d_all = dense_distance(x.detach(), distance, n_space)  # (B, N, N)
    losses = []
    tp = n_pred = n_edges = 0
    t = float(tau.detach())
    for b, (e, n) in enumerate(zip(edges, n_vertices, strict=True)):
        with torch.no_grad():
            d = torch.triu(d_all[b, :n, :n], diagonal=1)
            upper = torch.ones(n, n, dtype=torch.bool, device=x.device).triu(1)
            is_edge = torch.zeros(n, n, dtype=torch.bool, device=x.device)
            is_edge[e[:, 0], e[:, 1]] = True
            below = (d < t) & upper
            tp += int((below & is_edge).sum())
            n_pred += int(below.sum())
            n_edges += len(e)
            near = (d < t + sampling.margin) & upper & ~is_edge
            # the false positives (and those about to be) always, each for itself, so
            # that they get the false-positive weight; a subset of the other near ones
            close = near & (d < t + false_positive_margin)
            hard, w_hard = _subset(torch.nonzero(close), 4 * sampling.max_hard * len(e),
                                   generator)
            rest, w_rest = _subset(torch.nonzero(near & ~close), sampling.max_hard * len(e),
                                   generator)
            n_far = n * (n - 1) // 2 - len(e) - int(near.sum())
            m = sampling.random_negatives * len(e)
            i = torch.randint(0, n, (m,), generator=generator).to(x.device)
            j = torch.randint(0, n, (m,), generator=generator).to(x.device)
            lo, hi = torch.minimum(i, j), torch.maximum(i, j)
            far = (lo != hi) & ~near[lo, hi] & ~is_edge[lo, hi]
            rand = torch.stack([lo[far], hi[far]], 1)
            w_rand = max(n_far, 0) / max(len(rand), 1)
            negatives = torch.cat([hard, rest, rand])
            weights = torch.cat([
                torch.full((len(hard),), w_hard, device=x.device),
                torch.full((len(rest),), w_rest, device=x.device),
                torch.full((len(rand),), w_rand, device=x.device),
            ])
        losses.append(edge_loss_pairs(
            x[b], tau, e, negatives, weights, float(edge_weight(len(e), n)), distance,
            n_space, false_positive_weight, false_positive_margin,
        ))
    return EdgeLossResult(torch.stack(losses).mean(), tp, n_pred, n_edges)
