"""Held-out metrics of a trained model.

Connectivity on ground-truth vertices (the paper's training setting): edge F1 of the
pairs whose distance is below the threshold, and ``next`` accuracy of the mesh the decode
(:func:`spacemesh.decode.decode`) builds, both as :mod:`spacemesh.metrics.connectivity`
measures them.

Full pipeline (diffusion, then connectivity): the share of outputs that are valid closed
oriented manifolds (:func:`spacemesh.topology.check_topology`), and the Chamfer distance
and F1 to the ground truth as the paper computes them (:mod:`spacemesh.metrics.distance`:
sum of the two mean *squared* nearest distances over 10,000 points per surface; F1 at
0.02), in the normalised frame (longest axis spans [-1, 1]).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import torch

from spacemesh.decode import DecodeOptions, Embeddings, decode
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.connectivity import edge_f1_score, next_accuracy
from spacemesh.nn.model import SpaceMeshModel
from spacemesh.spacetime import edges_below_threshold
from spacemesh.topology import check_topology
from spacemesh.train.batching import Sample, collate

if TYPE_CHECKING:
    from spacemesh.runtime.pipeline import MeshGenerator


@torch.no_grad()
def predicted_embeddings(
    model: SpaceMeshModel, samples: Sequence[Sample], *, batch_size: int = 8
) -> list[Embeddings]:
    """The connectivity network's embeddings of each sample's ground-truth vertices.

    Parameters
    ----------
    model : SpaceMeshModel
    samples : sequence of Sample
    batch_size : int

    Returns
    -------
    list of Embeddings
        One per sample (float64, its ``n_vertices`` rows), with the model's ``tau``.
    """
    was_training = model.training
    model.eval()
    device = next(model.parameters()).device
    config = model.config
    out: list[Embeddings] = []
    for start in range(0, len(samples), batch_size):
        chunk = list(samples[start : start + batch_size])
        batch = collate(chunk, n_points=config.encoder.n_points, normals=config.encoder.normals,
                        connectivity=False).to(device)
        volumes = model.encoder(batch.points)
        *outputs, tau = model.connectivity(batch.positions, batch.valid, volumes)
        arrays = [a.double().cpu().numpy() for a in outputs]
        out.extend(_per_sample(chunk, arrays, float(tau.reshape(-1)[0])))
    model.train(was_training)
    return out


def _per_sample(chunk: Sequence[Sample], arrays: Sequence[np.ndarray], tau: float
                ) -> list[Embeddings]:
    """One batch's ``x, root, prev, next`` ``(B, N, .)`` cut into each sample's rows
    (float64)."""
    out = []
    for i, s in enumerate(chunk):
        x, root, prev, nxt = (np.asarray(a[i, : s.n_vertices], np.float64) for a in arrays)
        out.append(Embeddings(x, tau, root, prev, nxt))
    return out


def repository_embeddings(
    generator: MeshGenerator, samples: Sequence[Sample], *, batch_size: int = 8
) -> list[Embeddings]:
    """:func:`predicted_embeddings` of an exported model: its onnxruntime graphs.

    Parameters
    ----------
    generator : spacemesh.runtime.pipeline.MeshGenerator
    samples : sequence of Sample
    batch_size : int

    Returns
    -------
    list of Embeddings
        One per sample (float64, its ``n_vertices`` rows), with the graph's ``tau``.
    """
    spec = generator.spec
    out: list[Embeddings] = []
    for start in range(0, len(samples), batch_size):
        chunk = list(samples[start : start + batch_size])
        batch = collate(chunk, n_points=spec.n_points, normals=spec.normals,
                        connectivity=False)
        volumes = generator.backend.encode(batch.points.numpy())
        o = generator.backend.connect(batch.positions.numpy(), batch.valid.numpy(), volumes)
        out.extend(_per_sample(chunk, (o.x, o.root, o.prev, o.next), o.tau))
    return out


def decoded_scores(
    samples: Sequence[Sample], embeddings: Sequence[Embeddings], options: DecodeOptions
) -> dict[str, list[float]]:
    """Per-shape edge F1 (raw and decoded), ``next`` accuracy and exactness.

    Parameters
    ----------
    samples : sequence of Sample
    embeddings : sequence of Embeddings
        One per sample.
    options : DecodeOptions

    Returns
    -------
    dict of lists
        ``edge_f1`` (the pairs below the threshold, as
        :mod:`spacemesh.metrics.connectivity` measures it), ``decoded_edge_f1`` (the
        edges the decode keeps), ``next_accuracy`` (of the decoded mesh) and ``exact``
        (1.0 where the decode equals the truth).
    """
    scores: dict[str, list[float]] = {k: [] for k in SCORES}
    for s, emb in zip(samples, embeddings, strict=True):
        n = s.n_vertices
        result = decode(s.positions, emb, options, points=s.points)
        truth = s.connectivity
        raw = edges_below_threshold(emb.adjacency, emb.tau, options.distance, options.n_space)
        scores["edge_f1"].append(edge_f1_score(raw, truth.edges, n))
        scores["decoded_edge_f1"].append(edge_f1_score(result.connectivity.edges, truth.edges, n))
        scores["next_accuracy"].append(next_accuracy(result.connectivity, truth))
        scores["exact"].append(float(
            result.mesh.n_vertices == n
            and result.connectivity.edges.shape == truth.edges.shape
            and scores["next_accuracy"][-1] == 1.0 and scores["edge_f1"][-1] == 1.0
        ))
    return scores


#: The per-shape scores of :func:`decoded_scores`.
SCORES = ("edge_f1", "decoded_edge_f1", "next_accuracy", "exact")


def connectivity_metrics(
    model: SpaceMeshModel | MeshGenerator, samples: Sequence[Sample], *, batch_size: int = 8,
    options: DecodeOptions | None = None,
) -> dict[str, float]:
    """Edge F1 and ``next`` accuracy of the connectivity network on ground-truth vertices.

    Parameters
    ----------
    model : SpaceMeshModel or MeshGenerator
        The torch model, or an exported one (its onnxruntime graphs).
    samples : sequence of Sample
    batch_size : int
    options : DecodeOptions, optional
        Default: the model's (``model.decode_options``, or the generator's manifest).

    Returns
    -------
    dict
        Means over shapes of the scores of :func:`decoded_scores`, and ``shapes``.
    """
    if isinstance(model, SpaceMeshModel):
        embeddings = predicted_embeddings(model, samples, batch_size=batch_size)
        options = options or model.decode_options
    else:
        embeddings = repository_embeddings(model, samples, batch_size=batch_size)
        options = options or model.spec.decode
    scores = decoded_scores(samples, embeddings, options)
    means = {k: float(np.mean(v)) if v else float("nan") for k, v in scores.items()}
    return {**means, "shapes": float(len(samples))}


def surface_scores(pred: PolygonMesh, truth: PolygonMesh, seed: int = 0) -> dict[str, float]:
    """Chamfer distance and F1 of two surfaces (:func:`spacemesh.metrics.distance.chamfer_f1`
    on 10,000 points each), or infinities when the prediction has no area.

    Parameters
    ----------
    pred, truth : PolygonMesh
        In the same (normalised) frame.
    seed : int

    Returns
    -------
    dict
        ``chamfer`` and ``f1``.
    """
    from spacemesh.metrics.distance import chamfer_f1
    from spacemesh.metrics.sampling import sample_mesh

    a, b = sample_mesh(pred, seed=seed), sample_mesh(truth, seed=seed + 1)
    if len(a) == 0 or len(b) == 0:
        return {"chamfer": float("inf"), "f1": 0.0}
    scores = chamfer_f1(a.points, b.points)
    return {"chamfer": scores.chamfer, "f1": scores.f1}


def pipeline_metrics(
    generator, records: Sequence, *, steps: int | None = None, method: str | None = None,
    seed: int = 0, batch_size: int = 4,
) -> dict[str, float]:
    """Validity and Chamfer distance of the networks' own pipeline on held-out shapes:
    diffusion from pure noise, connectivity and decode, no geometry stage (``start=noise``,
    ``raw``), so that it measures what training changed.

    Parameters
    ----------
    generator : spacemesh.runtime.pipeline.MeshGenerator
    records : sequence of MeshRecord
        Shapes in the normalised frame; their point clouds condition the generation.
    steps : int, optional
    method : str, optional
    seed : int
        Request ``i`` uses ``seed + i``.
    batch_size : int
        Requests per onnxruntime batch.

    Returns
    -------
    dict
        ``valid`` (share of outputs without any topological defect: closed, manifold,
        consistently oriented; an empty output has none), ``valid_nonempty`` (the same
        among outputs with faces), ``empty`` (share without faces), ``chamfer_mean``,
        ``chamfer_median`` and ``f1_mean`` (over non-empty outputs), ``vertices_mean``
        and ``shapes``.
    """
    from spacemesh.runtime.options import GenerateOptions
    from spacemesh.runtime.request import GenerateRequest

    valid, empty, chamfer, f1, vertices = [], [], [], [], []
    for start in range(0, len(records), batch_size):
        chunk = list(records[start : start + batch_size])
        requests = [
            GenerateRequest(points=r.points, normals=r.normals, options=GenerateOptions(
                seed=seed + start + i, steps=steps, sampler=method, start="noise", raw=True))
            for i, r in enumerate(chunk)
        ]
        for record, result in zip(chunk, generator.generate_batch(requests), strict=True):
            mesh = result.mesh
            report = check_topology(mesh)
            empty.append(mesh.n_faces == 0)
            # no defect of any kind; the empty mesh (no faces) has none
            valid.append(report.is_manifold and report.is_closed and report.is_oriented)
            vertices.append(mesh.n_vertices)
            if mesh.n_faces:
                scores = surface_scores(mesh, record.mesh)
                chamfer.append(scores["chamfer"])
                f1.append(scores["f1"])
    nonempty = [v for v, e in zip(valid, empty, strict=True) if not e]
    return {
        "valid": float(np.mean(valid)) if valid else float("nan"),
        "valid_nonempty": float(np.mean(nonempty)) if nonempty else float("nan"),
        "empty": float(np.mean(empty)) if empty else float("nan"),
        "chamfer_mean": float(np.mean(chamfer)) if chamfer else float("nan"),
        "chamfer_median": float(np.median(chamfer)) if chamfer else float("nan"),
        "f1_mean": float(np.mean(f1)) if f1 else float("nan"),
        "vertices_mean": float(np.mean(vertices)) if vertices else float("nan"),
        "shapes": float(len(valid)),
    }


@torch.no_grad()
def calibrate_threshold(
    samples: Sequence[Sample], embeddings: Sequence[Embeddings], options: DecodeOptions, *,
    candidates: int = 400,
) -> tuple[float, float]:
    """The edge threshold ``tau`` that maximises the mean edge F1 on ground-truth vertices.

    Eq. 3 weighs non-edges by ``lambda = 4E/V^2``, which pushes the learned ``tau`` toward
    recall; a network that cannot yet separate all pairs then predicts too many edges.
    Choosing ``tau`` on validation shapes (never the held-out ones) fixes the calibration
    without touching the embeddings.

    Parameters
    ----------
    samples : sequence of Sample
    embeddings : sequence of Embeddings
        The network's, one per sample (:func:`predicted_embeddings`).
    options : DecodeOptions
        Its distance and ``n_space``.
    candidates : int
        Thresholds tried (quantiles of the pair distances).

    Returns
    -------
    tau : float
        The best threshold.
    f1 : float
        Its mean edge F1 on ``samples``.
    """
    shapes = _pair_distances(samples, embeddings, options)
    pooled = np.concatenate([d[y] for d, y, _ in shapes])  # distances of true edges
    grid = np.unique(np.quantile(pooled, np.linspace(0.0, 1.0, candidates)))
    scores = np.zeros(len(grid))
    for d, y, n_edges in shapes:
        order = np.argsort(d)
        below = np.searchsorted(d[order], grid, side="left")  # predicted edges per threshold
        hits = np.concatenate([[0], np.cumsum(y[order])])[below]  # true positives
        scores += 2 * hits / np.maximum(below + n_edges, 1)
    best = int(np.argmax(scores))
    return float(grid[best]), float(scores[best] / max(len(shapes), 1))


def _pair_distances(
    samples: Sequence[Sample], embeddings: Sequence[Embeddings], options: DecodeOptions
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """Per shape: the distances ``(P,)`` of its unordered vertex pairs, which of them
    are edges ``(P,)``, and its edge count."""
    from spacemesh.spacetime import pairwise_distance

    shapes = []
    for s, emb in zip(samples, embeddings, strict=True):
        n = s.n_vertices
        d = pairwise_distance(emb.adjacency, None, options.distance, options.n_space)
        iu = np.triu_indices(n, 1)
        truth = np.zeros((n, n), bool)
        e = s.connectivity.edges
        truth[e[:, 0], e[:, 1]] = True
        shapes.append((d[iu], truth[iu], len(e)))
    return shapes


#: Candidate edge counts of :func:`calibrate_decode_threshold`, relative to the count at
#: the F1-best threshold (the decode removes weak false edges, so it can take more).
DECODE_PAIR_RATIOS = (1.0, 1.1, 1.2, 1.3, 1.4, 1.5)


def calibrate_decode_threshold(
    samples: Sequence[Sample], embeddings: Sequence[Embeddings], options: DecodeOptions,
    tau: float, *, ratios: Sequence[float] = DECODE_PAIR_RATIOS,
) -> tuple[float, dict[str, float]]:
    """Of thresholds at or above ``tau``, the one whose decoded meshes are best.

    :func:`calibrate_threshold` maximises the edge F1 of the thresholded pairs. The
    decode then drops weak false edges (crossing diagonals, pinched faces), so a
    slightly looser threshold, which finds more of the true edges, can give better
    meshes. The candidates pass ``ratio`` times as many pairs as ``tau`` does, over all
    ``samples``; the one with the highest mean decoded ``next`` accuracy wins.

    Parameters
    ----------
    samples : sequence of Sample
        Validation shapes (never the held-out ones).
    embeddings : sequence of Embeddings
        The network's, one per sample (:func:`predicted_embeddings`).
    options : DecodeOptions
        The decode the model ships with.
    tau : float
        The F1-calibrated threshold (ratio 1).
    ratios : sequence of float

    Returns
    -------
    tau : float
        The chosen threshold.
    scores : dict
        Its means of :func:`decoded_scores`, and ``ratio``.
    """
    pooled = np.sort(np.concatenate(
        [d for d, _, _ in _pair_distances(samples, embeddings, options)]
    ))
    base = int(np.searchsorted(pooled, tau, side="left"))  # pairs below tau
    best: tuple[float, dict[str, float]] | None = None
    for ratio in ratios:
        count = min(round(base * ratio), len(pooled) - 1)
        if ratio != 1.0 and count <= base:
            continue  # no pair to add
        candidate = tau if ratio == 1.0 else float(0.5 * (pooled[count - 1] + pooled[count]))
        at = [Embeddings(e.adjacency, candidate, e.root, e.prev, e.next) for e in embeddings]
        means = {k: float(np.mean(v)) for k, v in decoded_scores(samples, at, options).items()}
        means["ratio"] = float(ratio)
        if best is None or means["next_accuracy"] > best[1]["next_accuracy"]:
            best = (candidate, means)
    assert best is not None
    return best
