"""Fitting a collection of meshes with one autodecoder (paper Sec. 4.2, Supplement B).

The torch side of ``spacemesh fit-collection``; the numpy core never imports it.

:class:`~spacemesh.fitting.collection_model.CollectionDecoder` decodes one latent code
per mesh into ``N`` vertex tokens (``N``: the largest mesh's vertex count). Latent codes,
positional embedding and transformer are trained jointly with Adam on

- the L2 loss of the positions, each mesh's over its own vertex slots, and of the mask
  channel (+1 vertex, -1 padding) over all ``N`` slots, against the mesh normalised to
  [-1, 1] and sorted z-y-x (slot ``i`` is the ``i``-th vertex in that order: the paper's
  ordering, no matching);
- the edge loss of Eq. 3 (``lambda = 4 E / V^2``) and the permutation loss of Eq. 5, the
  same losses (and the same false-positive weighting) as single-mesh fitting; the edge
  loss on sampled pairs, as single-mesh fitting's sparse mode
  (:mod:`~spacemesh.fitting.collection_losses`).

Scores (per mesh, then means): vertex L2 (mean squared error of the coordinates of the
mesh's vertices in the [-1, 1] frame), edge F1 on all pairs, ``next`` accuracy and
exactness of the numpy decode (:mod:`~spacemesh.fitting.collection_scores`).

Modules: ``collection_config`` (settings), ``collection_data`` (reading, normalising),
``collection_model`` (the decoder), ``collection_losses`` (the sampled edge loss),
``collection_scores`` (scores, decoding, gallery) and this one (training, checkpoints).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from spacemesh.errors import SpaceMeshError
from spacemesh.fitting.collection_config import FIXED_SETTINGS, CollectionConfig
from spacemesh.fitting.collection_data import CollectionMesh
from spacemesh.fitting.collection_losses import sampled_edge_loss
from spacemesh.fitting.collection_model import CollectionDecoder
from spacemesh.fitting.collection_scores import (
    MeshScore,
    decode_meshes,
    evaluate,
    score_mesh,
    write_gallery,
)
from spacemesh.nn.losses import degree_groups, permutation_loss
from spacemesh.threads import limit_threads
from spacemesh.train.batching import concat_connectivity

__all__ = [
    "CHECKPOINT", "GALLERY", "LOG", "SCORES", "CollectionConfig", "CollectionResult",
    "MeshScore", "StepRecord", "decode_meshes", "evaluate", "fit_collection", "load_run",
    "score_mesh", "write_gallery",
]

#: File of the newest checkpoint in a run folder.
CHECKPOINT = "checkpoint.pt"
#: Per-step log of a run (CSV).
LOG = "log.csv"
#: Collection scores of a run (the ``--json`` object).
SCORES = "scores.json"
#: Decoded meshes next to their originals.
GALLERY = "gallery.png"


@dataclass
class StepRecord:
    """One logged step (scores pooled over the step's meshes; cheap proxies)."""

    step: int
    seconds: float
    loss: float
    position_loss: float
    edge_loss: float
    perm_loss: float
    edge_f1: float
    next_accuracy: float


@dataclass
class CollectionResult:
    """Outcome of :func:`fit_collection`."""

    iterations: int
    seconds: float
    scores: list[MeshScore]
    history: list[StepRecord] = field(default_factory=list)

    @property
    def exact(self) -> bool:
        """Every mesh decodes exactly."""
        return all(s.exact for s in self.scores)

    def summary(self) -> dict:
        """The ``--json`` object: the keys of ``spacemesh fit --json``, with ``exact``,
        ``edge_f1``, ``next_accuracy`` and ``vertex_l2`` the means over the meshes
        (``exact``: the exact-decode rate), vertex and face counts the totals."""
        s = self.scores
        n = max(len(s), 1)
        return {
            "exact": round(sum(m.exact for m in s) / n, 6),
            "iterations": self.iterations,
            "seconds": round(self.seconds, 3),
            "n_vertices": sum(m.n_vertices for m in s),
            "n_faces": sum(m.n_faces for m in s),
            "edge_f1": round(sum(m.edge_f1 for m in s) / n, 6),
            "next_accuracy": round(sum(m.next_accuracy for m in s) / n, 6),
            "vertex_l2": float(f"{sum(m.vertex_l2 for m in s) / n:.4g}"),
            "n_meshes": len(s),
            "n_exact": sum(m.exact for m in s),
            "meshes": [m.summary(self.iterations, self.seconds) for m in s],
        }


def _targets(meshes: Sequence[CollectionMesh], n_tokens: int) -> torch.Tensor:
    """Positions and mask channel ``(M, N, 4)``: zeros and -1 in the padding."""
    target = torch.zeros(len(meshes), n_tokens, 4)
    target[..., 3] = -1.0
    for b, m in enumerate(meshes):
        target[b, : m.mesh.n_vertices, :3] = torch.as_tensor(m.mesh.vertices)
        target[b, : m.mesh.n_vertices, 3] = 1.0
    return target


class _Batches:
    """Ground truth of batches of meshes, built once per batch composition."""

    def __init__(self, meshes: Sequence[CollectionMesh], n_tokens: int, device: str) -> None:
        self.meshes, self.n_tokens, self.device = meshes, n_tokens, device
        self.target = _targets(meshes, n_tokens).to(device)  # (M, N, 4)
        self._cache: dict[tuple[int, ...], tuple] = {}

    def get(self, indices: Sequence[int]) -> tuple:
        key = tuple(indices)
        if key not in self._cache:
            edges = [torch.as_tensor(self.meshes[i].connectivity.edges, device=self.device)
                     for i in key]
            n_vertices = [self.meshes[i].mesh.n_vertices for i in key]
            conn = concat_connectivity([self.meshes[i].connectivity for i in key], self.n_tokens)
            groups = degree_groups(conn, self.device)
            n_rows = sum(int(g.target.numel()) for g in groups)
            batch = (torch.as_tensor(key, device=self.device), edges, n_vertices, groups,
                     n_rows)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = batch
        return self._cache[key]


def _position_loss(positions: torch.Tensor, mask: torch.Tensor, target: torch.Tensor,
                   per_vertex: bool) -> torch.Tensor:
    """The L2 loss of the positions ``(B, N, 3)`` and the mask channel ``(B, N)`` against
    ``target`` ``(B, N, 4)`` (positions, then +1 for a vertex and -1 for padding).

    ``per_vertex``: each mesh's mean squared coordinate error over its own vertex slots
    (the scored vertex L2), averaged over the meshes, plus the mask's mean squared error
    over all slots; the padding's positions are free. Otherwise the mean over all ``N``
    slots and the four channels, where the padding's zeros dilute a mesh of ``V``
    vertices' positions by ``V / N`` (a 24-vertex mesh among 2,000-vertex ones: 1 %).
    """
    if not per_vertex:
        predicted = torch.cat([positions, mask[..., None]], -1)
        return ((predicted - target) ** 2).mean()
    real = (target[..., 3] > 0).to(positions.dtype)  # (B, N)
    squared = ((positions - target[..., :3]) ** 2).sum(-1)  # (B, N)
    per_mesh = (squared * real).sum(1) / (3.0 * real.sum(1).clamp(min=1.0))  # (B,)
    return per_mesh.mean() + ((mask - target[..., 3]) ** 2).mean()


def _mean_edge(m: CollectionMesh) -> float:
    v, e = m.mesh.vertices, m.connectivity.edges
    return max(float(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1).mean()), 1e-6)


def _save(path: Path, state: dict) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)


def _mesh_card(m: CollectionMesh) -> dict:
    return {"name": m.name, "digest": m.digest, "n_vertices": m.mesh.n_vertices,
            "centre": m.centre.tolist(), "scale": m.scale}


def load_run(run: str | Path, device: str = "cpu") -> tuple[CollectionDecoder, dict]:
    """The decoder of a run folder and its checkpoint (config, meshes, step, seconds).

    Raises
    ------
    SpaceMeshError
        No checkpoint in ``run``.
    """
    path = Path(run) / CHECKPOINT
    if not path.is_file():
        raise SpaceMeshError(f"{run}: no {CHECKPOINT} (not a fit-collection run)")
    state = torch.load(path, map_location=device, weights_only=True)
    state["config"] = json.loads(state["config"])
    state["meshes"] = json.loads(state["meshes"])
    fixed = {k: state["config"][k] for k in FIXED_SETTINGS if k in state["config"]}
    shape = CollectionConfig(**fixed).shape(len(state["meshes"]), int(state["n_tokens"]))
    model = CollectionDecoder(shape, state["config"]["embedding_scale"]).to(device)
    model.load_state_dict(state["model"])
    return model, state


def fit_collection(
    meshes: Sequence[CollectionMesh],
    run: str | Path,
    config: CollectionConfig | None = None,
    resume: bool = False,
    callback: Callable[[StepRecord], None] | None = None,
) -> CollectionResult:
    """Train the autodecoder on ``meshes``, checkpointing into ``run``.

    Parameters
    ----------
    meshes : sequence of CollectionMesh
        From :func:`spacemesh.fitting.collection_data.load_collection`.
    run : path
        Run folder: ``checkpoint.pt``, ``log.csv``, ``scores.json``.
    config : CollectionConfig, optional
    resume : bool
        Continue from ``run``'s checkpoint (the same meshes, in the same order).
    callback : callable, optional
        Called with a :class:`StepRecord` after every step.

    Returns
    -------
    CollectionResult
        Scored on every mesh after the last step.

    Raises
    ------
    SpaceMeshError
        Nothing to fit, or a checkpoint that does not match ``meshes``.
    """
    config = config or CollectionConfig()
    if not meshes:
        raise SpaceMeshError("no meshes to fit")
    if config.threads is not None:
        limit_threads(config.threads)
    run = Path(run)
    run.mkdir(parents=True, exist_ok=True)
    cards = [_mesh_card(m) for m in meshes]
    n_tokens = max(m.mesh.n_vertices for m in meshes)
    step, seconds_before = 0, 0.0
    state = None
    if resume:
        model, state = load_run(run, config.device)
        if [(c["name"], c["digest"]) for c in state["meshes"]] != [
            (c["name"], c["digest"]) for c in cards
        ]:
            raise SpaceMeshError(f"{run}: the checkpoint was trained on other meshes")
        config = replace(config, **{k: state["config"][k] for k in FIXED_SETTINGS})
        step, seconds_before = int(state["step"]), float(state["seconds"])
    torch.manual_seed(config.seed + step)
    if state is None:
        model = CollectionDecoder(
            config.shape(len(meshes), n_tokens), config.embedding_scale, config.latent_std
        ).to(config.device)
        with torch.no_grad():  # positions in units of each mesh's mean edge length
            model.log_scale.copy_(torch.as_tensor([-np.log(_mean_edge(m)) for m in meshes]))
    codes = [model.latents.weight, model.positional, model.log_scale]
    rest = [p for p in model.parameters() if all(p is not c for c in codes)]
    code_lr = config.code_lr if config.code_lr is not None else config.lr
    optimizer = torch.optim.Adam([{"params": codes, "lr": code_lr, "base": code_lr},
                                  {"params": rest, "lr": config.lr, "base": config.lr}])
    if state is not None:
        optimizer.load_state_dict(state["optimizer"])
        for group, base in zip(optimizer.param_groups, (code_lr, config.lr), strict=True):
            group["base"] = base  # this call's rates, not the checkpoint's
    batches = _Batches(meshes, n_tokens, config.device)
    rng = np.random.default_rng(config.seed + step)
    generator = torch.Generator().manual_seed(config.seed + step)
    n_space = config.adjacency_dim // 2

    def save() -> None:
        _save(run / CHECKPOINT, {
            "format": "spacemesh-collection", "step": step,
            "seconds": seconds_before + time.perf_counter() - start,
            "n_tokens": n_tokens,
            "config": json.dumps(asdict(config)), "meshes": json.dumps(cards),
            "model": model.state_dict(), "optimizer": optimizer.state_dict(),
        })

    log_path = run / LOG
    if not (resume and log_path.is_file()):
        log_path.write_text(",".join(StepRecord.__dataclass_fields__) + "\n")
    log = log_path.open("a")
    history: list[StepRecord] = []
    start = time.perf_counter()
    last_save = start
    full = len(meshes) <= config.batch_size
    scores: list[MeshScore] | None = None
    try:
        while config.max_steps is None or step < config.max_steps:
            if config.max_seconds is not None and time.perf_counter() - start > config.max_seconds:
                break
            if full:
                indices = list(range(len(meshes)))
            else:
                indices = sorted(rng.choice(len(meshes), config.batch_size, replace=False))
            index, edges, n_vertices, groups, n_rows = batches.get(indices)
            step += 1
            for g in optimizer.param_groups:
                g["lr"] = g["base"] * min(1.0, step / max(config.warmup, 1))
            optimizer.zero_grad(set_to_none=True)
            out = model(index)
            target = batches.target[index]  # (B, N, 4)
            position_loss = _position_loss(out.positions, out.mask, target,
                                           config.per_vertex_positions)
            edge = sampled_edge_loss(
                out.x, out.tau, edges, n_vertices, config.sampling, generator,
                config.distance, n_space, config.false_positive_weight,
                config.false_positive_margin,
            )
            edge_loss = edge.loss
            k = out.root.shape[-1]
            perm_loss, correct = permutation_loss(
                groups, out.root.reshape(-1, k), out.prev.reshape(-1, k),
                out.next.reshape(-1, k), model.reduction, config.sinkhorn_iters,
            )
            loss = config.position_weight * position_loss + edge_loss + perm_loss
            loss.backward()
            if config.clip is not None:
                torch.nn.utils.clip_grad_norm_(model.parameters(), config.clip)
            optimizer.step()
            edge_f1 = 2 * edge.true_positives / max(edge.predicted + edge.edges, 1)
            next_acc = int(correct) / max(n_rows, 1)
            record = StepRecord(
                step, seconds_before + time.perf_counter() - start, loss.item(),
                position_loss.item(), edge_loss.item(), perm_loss.item(), edge_f1, next_acc,
            )
            history.append(record)
            log.write(",".join(f"{v:.6g}" if isinstance(v, float) else str(v)
                               for v in asdict(record).values()) + "\n")
            log.flush()
            if callback is not None:
                callback(record)
            if full and edge_f1 == 1.0 and next_acc == 1.0 and step % config.check_every == 0:
                scores = evaluate(model, meshes, config)
                if all(s.exact and s.vertex_l2 <= config.l2_target for s in scores):
                    break
                scores = None
            if time.perf_counter() - last_save > config.checkpoint_seconds:
                save()
                last_save = time.perf_counter()
    finally:
        log.close()
    save()
    seconds = seconds_before + time.perf_counter() - start
    if scores is None:
        scores = evaluate(model, meshes, config)
    result = CollectionResult(step, seconds, scores, history)
    (run / SCORES).write_text(json.dumps(result.summary(), indent=1) + "\n")
    return result
