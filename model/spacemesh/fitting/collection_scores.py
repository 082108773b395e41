"""Scores and decoding of a collection fit: the numpy decode of each mesh's tokens.

Per mesh, on all pairs of its ``V`` true vertices (its first ``V`` tokens): vertex L2
(mean squared error of the coordinates in the [-1, 1] frame), edge F1, ``next`` accuracy
of the decode and exactness; and the meshes a user gets (``--decode``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from spacemesh.decode import MAX_DEGREE, DecodeOptions, Embeddings, decode
from spacemesh.fitting.collection_config import FIXED_SETTINGS, CollectionConfig
from spacemesh.fitting.collection_data import CollectionMesh
from spacemesh.fitting.collection_model import CollectionDecoder, DecodedTokens
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.connectivity import next_accuracy
from spacemesh.spacetime import count_pairs_below_threshold, distance_operands


@dataclass
class MeshScore:
    """How well one mesh decodes (the keys of ``spacemesh fit --json`` plus L2)."""

    file: str
    exact: bool
    n_vertices: int
    n_faces: int
    edge_f1: float
    next_accuracy: float
    vertex_l2: float
    n_decoded_vertices: int
    decoded: PolygonMesh | None = None  # in the [-1, 1] frame

    def summary(self, iterations: int, seconds: float) -> dict:
        """This mesh's entry of the ``meshes`` list."""
        return {
            "file": self.file,
            "exact": self.exact,
            "iterations": iterations,
            "seconds": round(seconds, 3),
            "n_vertices": self.n_vertices,
            "n_faces": self.n_faces,
            "edge_f1": round(self.edge_f1, 6),
            "next_accuracy": round(self.next_accuracy, 6),
            "vertex_l2": float(f"{self.vertex_l2:.4g}"),
            "n_decoded_vertices": self.n_decoded_vertices,
        }


def decode_options(
    config: CollectionConfig, reduction_params: dict | None, n_raw: int, n_vertices: int
) -> DecodeOptions:
    """How a collection's tokens are decoded: as single-mesh fitting does, except that
    the decode uses no geometry: crossing quad diagonals are not dropped by position
    (``uncross``) and a vertex whose assignment is not one orbit gets the paper's greedy
    orbit instead of its neighbours by angle, because the decoded positions are only
    near the true ones (and a wrong angular order cascades through the unpinching).
    A sparse graph (at most ``4 V`` raw pairs) is decoded as it is, a dense one with the
    decode's degree bound."""
    return DecodeOptions(
        distance=config.distance,
        n_space=config.adjacency_dim // 2,
        reduction=config.reduction,
        reduction_params=reduction_params,
        sinkhorn_iters=config.sinkhorn_iters,
        max_degree=None if n_raw <= 4 * n_vertices else MAX_DEGREE,
        fallback="greedy",
        uncross=False,
    )


def _embeddings(out: DecodedTokens, b: int, rows: slice | np.ndarray) -> Embeddings:
    def np64(t: torch.Tensor) -> np.ndarray:
        return t[b][rows].detach().cpu().double().numpy()

    return Embeddings(
        np64(out.x), float(out.tau.detach()), np64(out.root), np64(out.prev), np64(out.next)
    )


def score_mesh(
    mesh: CollectionMesh, emb: Embeddings, positions: np.ndarray, mask: np.ndarray,
    config: CollectionConfig, reduction_params: dict | None,
) -> MeshScore:
    """Score one mesh's first ``V`` tokens against it, on all pairs.

    Parameters
    ----------
    mesh : CollectionMesh
    emb : Embeddings
        Of its ``V`` vertices.
    positions : (V, 3) float
        Decoded positions.
    mask : (N,) float
        The mask channel of all tokens.
    config : CollectionConfig
    reduction_params : dict, optional

    Returns
    -------
    MeshScore
        ``exact``: the decode's faces equal the mesh's, exactly ``E`` pairs are below the
        threshold, and the mask keeps exactly the ``V`` vertices.
    """
    n, truth = mesh.mesh.n_vertices, mesh.connectivity
    n_space = config.adjacency_dim // 2
    n_raw = count_pairs_below_threshold(emb.adjacency, emb.tau, config.distance, n_space)
    a, b = distance_operands(emb.adjacency, config.distance, n_space)
    e = truth.edges
    tp = int(((a[e[:, 0]] * b[e[:, 1]]).sum(-1) < emb.tau).sum())
    edge_f1 = 2 * tp / max(n_raw + len(e), 1)
    result = decode(positions, emb, decode_options(config, reduction_params, n_raw, n))
    mask_right = bool(np.all(mask[:n] > 0) and np.all(mask[n:] <= 0))
    exact = (
        n_raw == len(e) == tp
        and mask_right
        and result.mesh.n_vertices == n
        and result.mesh.face_key_set() == mesh.mesh.face_key_set()
    )
    return MeshScore(
        mesh.name, bool(exact), n, mesh.mesh.n_faces, float(edge_f1),
        next_accuracy(result.connectivity, truth),
        float(np.mean((positions - mesh.mesh.vertices) ** 2)),
        int((mask > 0).sum()), result.mesh,
    )


def evaluate(
    model: CollectionDecoder,
    meshes: Sequence[CollectionMesh],
    config: CollectionConfig,
    chunk: int = 8,
) -> list[MeshScore]:
    """Score every mesh (:func:`score_mesh`), decoding ``chunk`` meshes at a time."""
    reduction_params = model.reduction.numpy_params()
    device = next(model.parameters()).device
    scores = []
    model.eval()
    with torch.no_grad():
        for start in range(0, len(meshes), chunk):
            index = torch.arange(start, min(start + chunk, len(meshes)), device=device)
            out = model(index)
            for b, i in enumerate(index.tolist()):
                n = meshes[i].mesh.n_vertices
                positions = out.positions[b, :n].double().cpu().numpy()  # (V, 3)
                scores.append(score_mesh(
                    meshes[i], _embeddings(out, b, slice(0, n)), positions,
                    out.mask[b].cpu().numpy(), config, reduction_params,
                ))
    model.train()
    return scores


def decode_meshes(model: CollectionDecoder, state: dict) -> list[tuple[str, PolygonMesh]]:
    """Decode every mesh of a run as a user gets it: the tokens whose mask channel is
    positive, the numpy decode, positions back in the original frame.

    Returns
    -------
    list of (file name, PolygonMesh)
    """
    config = CollectionConfig(**{k: state["config"][k] for k in FIXED_SETTINGS})
    reduction_params = model.reduction.numpy_params()
    device = next(model.parameters()).device
    decoded = []
    model.eval()
    with torch.no_grad():
        for i, card in enumerate(state["meshes"]):
            out = model(torch.tensor([i], device=device))
            alive = np.flatnonzero(out.mask[0].cpu().numpy() > 0)
            emb = _embeddings(out, 0, alive)
            positions = out.positions[0].double().cpu().numpy()[alive]  # (V', 3)
            n_raw = count_pairs_below_threshold(
                emb.adjacency, emb.tau, config.distance, config.adjacency_dim // 2
            )
            options = decode_options(config, reduction_params, n_raw, len(alive))
            mesh = decode(positions, emb, options).mesh
            centre, scale = np.asarray(card["centre"]), float(card["scale"])
            decoded.append((card["name"], mesh.with_vertices(mesh.vertices * scale + centre)))
    return decoded


def write_gallery(
    meshes: Sequence[CollectionMesh], scores: Sequence[MeshScore], path: str | Path,
    max_rows: int = 12,
) -> Path:
    """A PNG of the first ``max_rows`` meshes: original and decoded, side by side."""
    from spacemesh.evaluate.gallery import GalleryRow, render_gallery

    rows = [
        GalleryRow(
            f"{m.name} ({'exact' if s.exact else f'F1 {s.edge_f1:.3f}'})",
            m.mesh.vertices,
            {"gt": m.mesh, "ours": s.decoded},
        )
        for m, s in list(zip(meshes, scores, strict=True))[:max_rows]
    ]
    return render_gallery(
        rows, path, columns=("gt", "ours"),
        labels={"gt": "original", "ours": "decoded"}, cell_inches=2.2,
    )
