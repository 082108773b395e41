"""Helpers of the repair tests: numpy stand-ins for the three networks, and comparisons.

``NoiseBackend`` is an untrained-looking model (arbitrary denoiser, random embeddings):
whatever it predicts, a repair must keep the outside identical and close the hole.
``OracleBackend`` knows the original mesh: its denoiser drives the free tokens onto the
removed vertices and its connectivity network returns embeddings fitted to the original,
so a correct pipeline gives the original mesh back.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from spacemesh.decode import DecodeOptions, Embeddings
from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.backend import ConnectivityOutputs
from spacemesh.runtime.schedule import NoiseSchedule
from spacemesh.runtime.spec import ModelSpec
from tests.validity import assert_valid_mesh

K, N_SPACE, KP = 16, 8, 6


def make_spec(max_vertices: int = 64, steps: int = 8, timesteps: int = 64) -> ModelSpec:
    """A model description matching the fakes (k = 16 split 8 + 8, k_p = 6)."""
    return ModelSpec(n_points=128, max_vertices=max_vertices, normals=False,
                     schedule=NoiseSchedule.from_config("cosine", timesteps), method="ddim",
                     steps=steps, decode=DecodeOptions(n_space=N_SPACE))


class NoiseBackend:
    """Arbitrary but deterministic networks (seeded by ``seed``)."""

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed
        self.calls = {"encode": 0, "denoise": 0, "connect": 0}

    def encode(self, points: np.ndarray) -> list[np.ndarray]:
        self.calls["encode"] += 1
        return [np.zeros((len(points), 1, 2, 2, 2), np.float32)]

    def denoise(self, x_t: np.ndarray, t: np.ndarray, volumes: list[np.ndarray]) -> np.ndarray:
        self.calls["denoise"] += 1
        rng = np.random.default_rng([self.seed, int(t[0])])
        return (0.3 * rng.standard_normal(x_t.shape) + 0.5 * x_t).astype(np.float32)

    def connect(self, vertices: np.ndarray, valid: np.ndarray, volumes: list[np.ndarray]
                ) -> ConnectivityOutputs:
        self.calls["connect"] += 1
        rng = np.random.default_rng(self.seed + 1)
        b, n, _ = vertices.shape
        # embeddings that favour spatial neighbours, so faces are local but imperfect
        x = np.concatenate([4.0 * vertices, rng.normal(0, 0.3, (b, n, K - 3))], axis=-1)
        perm = [rng.normal(size=(b, n, KP)).astype(np.float32) for _ in range(3)]
        return ConnectivityOutputs(x.astype(np.float32), *perm, tau=1.5)


class OracleBackend:
    """Networks that know the answer.

    Parameters
    ----------
    targets : (T, 3) float
        The original vertices that the patch holds or must re-create, in the patch's
        unit frame.
    embeddings : Embeddings
        Fitted embeddings of those ``T`` vertices.
    schedule : NoiseSchedule
    """

    def __init__(self, targets: np.ndarray, embeddings: Embeddings,
                 schedule: NoiseSchedule) -> None:
        self.targets = np.asarray(targets, np.float64)
        self.embeddings = embeddings
        self.abar = schedule.alphas_cumprod

    def encode(self, points: np.ndarray) -> list[np.ndarray]:
        return [np.zeros((len(points), 1, 2, 2, 2), np.float32)]

    def denoise(self, x_t: np.ndarray, t: np.ndarray, volumes: list[np.ndarray]) -> np.ndarray:
        x = np.asarray(x_t[0], np.float64)  # (N, 4)
        a = float(self.abar[int(t[0])])
        n, n_targets = len(x), len(self.targets)
        cost = np.full((n, n), 0.5)  # tokens x (targets, then padding slots)
        cost[:, :n_targets] = np.sum(
            (x[:, None, :3] - math.sqrt(a) * self.targets[None]) ** 2, axis=-1)
        rows, cols = linear_sum_assignment(cost)
        x0 = np.empty_like(x)
        x0[:, :3] = np.clip(x[:, :3] / math.sqrt(a), -1, 1)
        x0[:, 3] = -1.0
        hit = cols < n_targets
        x0[rows[hit], :3] = self.targets[cols[hit]]
        x0[rows[hit], 3] = 1.0
        eps = (x - math.sqrt(a) * x0) / math.sqrt(1.0 - a)
        return eps[None].astype(np.float32)

    def connect(self, vertices: np.ndarray, valid: np.ndarray, volumes: list[np.ndarray]
                ) -> ConnectivityOutputs:
        _, nearest = cKDTree(self.targets).query(np.asarray(vertices[0], np.float64))
        e = self.embeddings
        parts = [a[nearest][None].astype(np.float32) for a in (e.adjacency, e.root, e.prev,
                                                               e.next)]
        return ConnectivityOutputs(*parts, tau=float(e.tau))


def subset(emb: Embeddings, rows: np.ndarray) -> Embeddings:
    """The embeddings of the vertices ``rows``."""
    return Embeddings(emb.adjacency[rows], emb.tau, emb.root[rows], emb.prev[rows],
                      emb.next[rows])


def fitted_embeddings(mesh: PolygonMesh) -> Embeddings:
    """Embeddings that decode exactly to ``mesh`` (direct optimisation, torch)."""
    from spacemesh.fitting import EmbeddingFitConfig, fit_mesh

    result = fit_mesh(mesh, EmbeddingFitConfig(threads=1))
    assert result.exact
    return result.embeddings


def geometric_faces(mesh: PolygonMesh, decimals: int = 5) -> set:
    """Faces as rotation-normalised tuples of rounded positions (index-free)."""
    keys = set()
    for face in mesh.faces:
        pts = [tuple(np.round(mesh.vertices[v], decimals) + 0.0) for v in face]
        start = min(range(len(pts)), key=lambda i: pts[i])
        keys.add(tuple(pts[start:] + pts[:start]))
    return keys


def assert_closed_manifold(mesh: PolygonMesh) -> None:
    """Non-empty, closed, oriented, manifold, no repeated vertex in a face, no unused
    vertex (:func:`tests.validity.assert_valid_mesh`)."""
    assert_valid_mesh(mesh)


def assert_outside_identical(original: PolygonMesh, result) -> None:
    """Every kept face is its input face: same positions, same cycle, same first corner."""
    kept = result.face_source >= 0
    n_kept = int(kept.sum())
    assert kept[:n_kept].all() and not kept[n_kept:].any()  # kept faces first
    sources = result.face_source[:n_kept]
    assert np.array_equal(sources, np.flatnonzero(~result.region))  # in input order
    out = result.mesh
    assert np.array_equal(out.face_sizes[:n_kept], original.face_sizes[sources])
    corners_in = ~result.region[original.face_of_corner]
    out_indices = out.face_indices[: out.face_offsets[n_kept]]
    in_indices = original.face_indices[corners_in]
    assert np.array_equal(result.vertex_map[in_indices], out_indices)
    assert np.array_equal(out.vertices[out_indices], original.vertices[in_indices])


def flat_shaded(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` with every face on vertices of its own (as a flat-shaded GLB stores it):
    the same positions and faces, split at every corner, so the mesh reads as fully open."""
    return PolygonMesh(mesh.vertices[mesh.face_indices], np.arange(len(mesh.face_indices)),
                       mesh.face_offsets)
