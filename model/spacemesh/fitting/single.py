"""Fitting SpaceMesh embeddings to one mesh by direct optimisation (paper Sec. 4.1).

The torch side of ``spacemesh fit`` (the training extra); the numpy core never imports it.

Per-vertex embeddings ``x`` (k = 16: 8 space + 8 time), ``y_root``, ``y_prev``,
``y_next`` (k_p = 6) and the threshold ``tau`` are optimised with Adam (lr 0.1) on the
losses of Eq. 3 and Eq. 5 until the numpy decode reproduces the input's faces exactly.

The edge loss covers every pair for meshes up to ``dense_limit`` vertices. Above that,
each step uses all edges, the non-edges currently within ``margin`` of the threshold
(mined on all pairs every ``mine_every`` steps), and uniformly sampled non-edges that
stand in for the rest. Exactness is always judged on all pairs by the decode.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from spacemesh.connectivity import Connectivity
from spacemesh.decode import MAX_DEGREE, DecodeOptions, DecodeResult, Embeddings, decode
from spacemesh.encode import encode_connectivity, require_closed_manifold
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.connectivity import edge_f1_score, next_accuracy
from spacemesh.nn.losses import (
    PermutationReduction,
    degree_groups,
    distance_operands,
    edge_loss_dense,
    edge_loss_pairs,
    edge_weight,
    permutation_loss,
)
from spacemesh.permutation import SINKHORN_ITERS
from spacemesh.spacetime import count_pairs_below_threshold, edges_below_threshold
from spacemesh.threads import limit_threads


@dataclass(frozen=True)
class EmbeddingFitConfig:
    """Settings of :func:`fit_mesh`: the paper's, plus the sparse-mode and
    false-positive options that make large meshes converge (docs/REPRESENTATION.md)."""

    adjacency_dim: int = 16
    n_space: int = 8
    permutation_dim: int = 6
    lr: float = 0.1
    max_iters: int = 1000
    distance: str = "spacetime"
    reduction: str = "product"
    seed: int = 0
    init_scale: float = 0.1
    sinkhorn_iters: int = SINKHORN_ITERS
    dense_limit: int = 1024
    mine_every: int = 5
    margin: float = 6.0
    random_negatives: int = 4  # per edge, in sparse mode
    max_hard: int = 8  # mined non-edges kept per edge, in sparse mode
    false_positive_weight: float | None = 1.0  # non-edges below tau; None: lambda for all (paper)
    threads: int | None = None  # None: as the process is; else spacemesh.threads.limit_threads
    # non-edges keep the false-positive weight until d > tau + margin (hysteresis)
    false_positive_margin: float = 0.5
    init: str = "random"  # or "positions": space coordinates start at the vertex positions
    # hubs take longer steps: x = (degree / mean degree) ** power * z (0: plain Adam)
    hub_step_power: float = 0.5


@dataclass
class EmbeddingFitRecord:
    """One logged optimisation step."""

    iteration: int
    loss: float
    edge_loss: float
    perm_loss: float
    edge_f1: float
    next_accuracy: float
    seconds: float


@dataclass
class EmbeddingFitResult:
    """Outcome of :func:`fit_mesh`."""

    exact: bool
    iterations: int
    seconds: float
    n_vertices: int
    n_faces: int
    edge_f1: float
    next_accuracy: float
    decoded: DecodeResult | None = None
    embeddings: Embeddings | None = None
    history: list[EmbeddingFitRecord] = field(default_factory=list)

    def summary(self) -> dict:
        """The JSON summary printed by ``spacemesh fit --json``."""
        return {
            "exact": self.exact,
            "iterations": self.iterations,
            "seconds": round(self.seconds, 3),
            "n_vertices": self.n_vertices,
            "n_faces": self.n_faces,
            "edge_f1": round(self.edge_f1, 6),
            "next_accuracy": round(self.next_accuracy, 6),
        }


#: With ``init="positions"``: the threshold's start, in squared mean edge lengths (edges
#: start near 1, the next ring near 3 to 4).
POSITIONS_TAU = 2.0
INITS = ("random", "positions")


#: Vertices of at least this many times the mean degree count as hubs.
HUB_RATIO = 2.0


def hub_step_scale(degrees: np.ndarray, power: float) -> np.ndarray:
    """Per-vertex scale of the adjacency embedding's steps: ``(degree / mean) ** power``
    for hubs (:data:`HUB_RATIO`), exactly 1 for every other vertex (so a mesh without
    hubs fits exactly as with plain Adam).

    A vertex of degree 100 must move far in embedding space (near all of its neighbours,
    away from other hubs) while Adam moves every coordinate by about ``lr`` per step;
    optimising ``z`` with ``x = scale * z`` lets hubs take proportionally longer steps.
    """
    ratio = degrees / max(float(degrees.mean()), 1.0)
    return np.where(ratio >= HUB_RATIO, ratio, 1.0) ** power


class _Parameters(torch.nn.Module):
    def __init__(self, mesh: PolygonMesh, edges: np.ndarray, config: EmbeddingFitConfig,
                 generator: torch.Generator, degrees: np.ndarray) -> None:
        super().__init__()
        n, s = mesh.n_vertices, config.init_scale

        def rand(*shape: int) -> torch.nn.Parameter:
            return torch.nn.Parameter(torch.randn(*shape, generator=generator) * s)

        self.z = rand(n, config.adjacency_dim)
        scale = hub_step_scale(degrees, config.hub_step_power)
        self.register_buffer("x_scale", torch.as_tensor(scale, dtype=self.z.dtype)[:, None])
        tau = 0.0
        if config.init == "positions":  # space coordinates in units of the mean edge
            v = mesh.vertices
            mean_edge = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1).mean()
            with torch.no_grad():
                start = (v - v.mean(0)) / max(float(mean_edge), 1e-12)
                self.z[:, :3] = torch.as_tensor(start, dtype=self.z.dtype) / self.x_scale
            tau = POSITIONS_TAU
        self.root = rand(n, config.permutation_dim)
        self.prev = rand(n, config.permutation_dim)
        self.next = rand(n, config.permutation_dim)
        self.tau = torch.nn.Parameter(torch.full((), tau))
        self.reduction = PermutationReduction(config.reduction, dim=config.permutation_dim)

    @property
    def x(self) -> torch.Tensor:
        """The adjacency embeddings ``(N, k)``."""
        return self.z * self.x_scale

    def embeddings(self) -> Embeddings:
        def np64(t: torch.Tensor) -> np.ndarray:
            return t.detach().double().numpy()

        return Embeddings(
            np64(self.x),
            float(self.tau.detach()),
            np64(self.root),
            np64(self.prev),
            np64(self.next),
        )


def _mine_near_pairs(
    x: torch.Tensor,
    tau: float,
    config: EmbeddingFitConfig,
    cap: int,
    generator: torch.Generator,
    block: int = 1024,
) -> torch.Tensor:
    """Pairs ``i < j`` with ``d < tau + margin``, about ``cap`` of the closest (no grad).

    When more than ``cap`` pairs are that close, the cut-off is lowered to the distance
    quantile that keeps about ``cap`` of them, estimated on a random sample of pairs.
    """
    with torch.no_grad():
        a, b = distance_operands(x, config.distance, config.n_space)
        n = len(x)
        n_pairs = n * (n - 1) // 2
        cutoff = tau + config.margin
        if cap < n_pairs:
            m = min(n_pairs, 200_000)
            i = torch.randint(0, n, (m,), generator=generator)
            j = torch.randint(0, n, (m,), generator=generator)
            sample = (a[i] * b[j]).sum(-1)[i != j]
            if len(sample):
                q = torch.quantile(sample.double(), min(1.0, cap / n_pairs)).item()
                cutoff = min(cutoff, q)
        pairs = []
        for start in range(0, n, block):
            d = a[start : start + block] @ b[start:].T  # (rows, n - start)
            ii, jj = torch.nonzero(torch.triu(d < cutoff, diagonal=1), as_tuple=True)
            pairs.append(torch.stack([ii + start, jj + start], 1))
        return torch.cat(pairs) if pairs else torch.zeros((0, 2), dtype=torch.long)


def _judge(
    mesh: PolygonMesh,
    truth: Connectivity,
    target_faces: set,
    params: _Parameters,
    config: EmbeddingFitConfig,
) -> tuple[DecodeResult, bool, float, float]:
    """Decode the current embeddings and compare with the input on all pairs.

    Returns the decode, exactness, edge F1 and next accuracy. Exact means: exactly as
    many pairs below the threshold as input edges, and the same faces (as cycles). The
    decode is the paper's (threshold, then the assignment per vertex), without the
    geometric steps of the generative pipeline (``DecodeOptions.uncross`` and the
    refinements), which may remove or flip true edges of a real mesh.
    """
    emb = params.embeddings()
    gt_edges = truth.edges
    n = mesh.n_vertices
    n_raw = count_pairs_below_threshold(emb.adjacency, emb.tau, config.distance, config.n_space)
    options = DecodeOptions(
        distance=config.distance,
        n_space=config.n_space,
        reduction=config.reduction,
        reduction_params=params.reduction.numpy_params(),
        sinkhorn_iters=config.sinkhorn_iters,
        # a sparse graph is decoded as it is (high-degree poles included); only a dense
        # one, which cannot be exact anyway, gets the decode's degree bound
        max_degree=None if n_raw <= 8 * len(gt_edges) else MAX_DEGREE,
        # the embeddings alone decide: the generator's geometric clean-up would drop true
        # edges that cross geometrically (a degree-3 vertex next to the opposite side of
        # its fan, coplanar low-poly facets), which no embedding can then bring back
        uncross=False,
    )
    result = decode(mesh.vertices, emb, options)
    exact = (
        n_raw == len(gt_edges)
        and result.mesh.n_vertices == n
        and result.mesh.face_key_set() == target_faces
    )
    if n_raw <= 8 * len(gt_edges):  # list every raw pair: the exact F1
        raw = edges_below_threshold(emb.adjacency, emb.tau, config.distance, config.n_space)
        edge_f1 = edge_f1_score(raw, gt_edges, n)
    else:  # too many pairs to list: a lower bound from the degree-bounded decode
        tp = len(gt_edges) + len(result.connectivity.edges)
        tp = tp * edge_f1_score(result.connectivity.edges, gt_edges, n) / 2
        edge_f1 = 2 * tp / (n_raw + len(gt_edges))
    return result, exact, edge_f1, next_accuracy(result.connectivity, truth)


def fit_mesh(
    mesh: PolygonMesh,
    config: EmbeddingFitConfig | None = None,
    callback: Callable[[EmbeddingFitRecord], None] | None = None,
    stop_when_exact: bool = True,
) -> EmbeddingFitResult:
    """Optimise per-vertex embeddings until they decode to ``mesh`` exactly.

    Parameters
    ----------
    mesh : PolygonMesh
        A closed oriented manifold polygon mesh; unreferenced vertices are dropped.
    config : EmbeddingFitConfig, optional
    callback : callable, optional
        Called with a :class:`EmbeddingFitRecord` after every step (progress bars, curves).
    stop_when_exact : bool
        Stop at the first step whose decode equals the input (else run ``max_iters``).

    Returns
    -------
    EmbeddingFitResult
        ``exact`` tells whether the decoded faces equal the input faces (as cyclic
        sequences); ``edge_f1`` and ``next_accuracy`` are measured on all pairs.
    """
    config = config or EmbeddingFitConfig()
    if config.init not in INITS:
        raise ValueError(f"unknown init {config.init!r}; expected one of {INITS}")
    if config.init == "positions" and config.distance == "dot":
        raise ValueError("init='positions' needs a distance with space coordinates, not 'dot'")
    if config.threads is not None:
        limit_threads(config.threads)
    require_closed_manifold(mesh)
    mesh, _ = mesh.remove_unreferenced_vertices()
    truth = encode_connectivity(mesh, check=False)
    target_faces = mesh.face_key_set()
    n = mesh.n_vertices
    gt_edges = truth.edges
    generator = torch.Generator().manual_seed(config.seed)
    params = _Parameters(mesh, gt_edges, config, generator, np.diff(truth.offsets))
    optimizer = torch.optim.Adam(params.parameters(), lr=config.lr)
    groups = degree_groups(truth)
    n_rows = sum(int(g.target.numel()) for g in groups)
    dense = n <= config.dense_limit
    positives = torch.as_tensor(gt_edges)
    gt_keys = torch.as_tensor(gt_edges[:, 0] * n + gt_edges[:, 1])
    lam = float(edge_weight(len(gt_edges), n))
    n_negatives_total = n * (n - 1) // 2 - len(gt_edges)
    if dense:
        adjacency = torch.zeros(1, n, n, dtype=torch.bool)
        adjacency[0, positives[:, 0], positives[:, 1]] = True
    hard = torch.zeros((0, 2), dtype=torch.long)

    history: list[EmbeddingFitRecord] = []
    start = time.perf_counter()
    result: DecodeResult | None = None
    exact = False
    edge_f1, next_acc = 0.0, 0.0
    iteration = 0
    for iteration in range(1, config.max_iters + 1):
        optimizer.zero_grad(set_to_none=True)
        if dense:
            e_loss = edge_loss_dense(
                params.x[None],
                params.tau,
                adjacency,
                None,
                config.distance,
                config.n_space,
                config.false_positive_weight,
                config.false_positive_margin,
            )
        else:
            if (iteration - 1) % config.mine_every == 0:
                near = _mine_near_pairs(
                    params.x, params.tau.item(), config, config.max_hard * len(gt_edges), generator
                )
                hard = near[~torch.isin(near[:, 0] * n + near[:, 1], gt_keys)]
            m = config.random_negatives * len(gt_edges)
            i = torch.randint(0, n, (m,), generator=generator)
            j = torch.randint(0, n, (m,), generator=generator)
            lo, hi = torch.minimum(i, j), torch.maximum(i, j)
            key = lo * n + hi
            keep = (
                (lo != hi)
                & ~torch.isin(key, gt_keys)
                & ~torch.isin(key, hard[:, 0] * n + hard[:, 1])
            )
            rand = torch.stack([lo[keep], hi[keep]], 1)
            w_rand = max(n_negatives_total - len(hard), 0) / max(len(rand), 1)
            negatives = torch.cat([hard, rand])
            weights = torch.cat([torch.ones(len(hard)), torch.full((len(rand),), w_rand)])
            e_loss = edge_loss_pairs(
                params.x,
                params.tau,
                positives,
                negatives,
                weights,
                lam,
                config.distance,
                config.n_space,
                config.false_positive_weight,
                config.false_positive_margin,
            )
        p_loss, correct = permutation_loss(
            groups, params.root, params.prev, params.next, params.reduction, config.sinkhorn_iters
        )
        loss = e_loss + p_loss
        loss.backward()
        optimizer.step()

        # cheap progress signals; the decode judges exactness only when they are perfect
        with torch.no_grad():
            if dense:
                d = (
                    distance_operands(params.x, config.distance, config.n_space)[0]
                    @ distance_operands(params.x, config.distance, config.n_space)[1].T
                )
                predicted = torch.triu(d < params.tau, diagonal=1)
                tp = int((predicted & adjacency[0]).sum())
                n_pred = int(predicted.sum())
            else:
                a, b = distance_operands(params.x, config.distance, config.n_space)
                tp = int(((a[positives[:, 0]] * b[positives[:, 1]]).sum(-1) < params.tau).sum())
                dh = (a[hard[:, 0]] * b[hard[:, 1]]).sum(-1) if len(hard) else torch.zeros(0)
                n_pred = tp + int((dh < params.tau).sum())
            edge_f1 = 2 * tp / max(n_pred + len(gt_edges), 1)
            next_acc = int(correct) / max(n_rows, 1)
        if edge_f1 == 1.0 and next_acc == 1.0:
            result, exact, edge_f1, next_acc = _judge(mesh, truth, target_faces, params, config)
        record = EmbeddingFitRecord(
            iteration,
            loss.item(),
            e_loss.item(),
            p_loss.item(),
            edge_f1,
            next_acc,
            time.perf_counter() - start,
        )
        history.append(record)
        if callback is not None:
            callback(record)
        if exact and stop_when_exact:
            break
    seconds = time.perf_counter() - start
    if result is None or not exact:
        result, exact, edge_f1, next_acc = _judge(mesh, truth, target_faces, params, config)
    return EmbeddingFitResult(
        exact=exact,
        iterations=iteration,
        seconds=seconds,
        n_vertices=n,
        n_faces=mesh.n_faces,
        edge_f1=edge_f1,
        next_accuracy=next_acc,
        decoded=result,
        embeddings=params.embeddings(),
        history=history,
    )
