"""Point cloud in, oriented manifold polygon mesh out: the full generation pipeline.

For each request:

1. normalise the points (bounding-box centre to the origin, longest axis to [-1, 1]);
2. subsample or pad them to the encoder's point count (deterministically);
3. encoder, once -> feature volumes;
4. sampler loop over the denoiser -> vertex tokens; the mask channel picks the vertices
   (coincident ones are merged);
5. connectivity network on those vertices -> SpaceMesh embeddings;
6. :func:`spacemesh.decode.decode` -> a valid oriented manifold mesh; faces are flipped
   if its signed volume is negative, so they face outward;
7. denormalise to the input frame and scale.

Requests of one :meth:`MeshGenerator.generate_batch` call share each network call
(one onnxruntime batch); each keeps its own seed, so batching never changes a result.
This module uses numpy and onnxruntime only (never torch).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh.data.validate import signed_volume
from spacemesh.decode import DecodeOptions, Embeddings, decode
from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.backend import Backend
from spacemesh.runtime.sampler import ProgressFn, sample, split_tokens
from spacemesh.runtime.schedule import METHODS, NoiseSchedule
from spacemesh.typed import FloatArray, IntArray

#: Seed of the fixed generator that picks the encoder's points from a larger cloud.
POINT_SUBSET_SEED = 0

#: Sampled vertices closer than this (normalised units) are one vertex: coincident
#: vertices (e.g. two tokens clipped to the same corner of the cube) would give the
#: connectivity network identical inputs, hence exact ties in the decode.
DUPLICATE_TOLERANCE = 1e-4


#: The manifest ``decode`` keys that are :class:`~spacemesh.decode.DecodeOptions` fields.
DECODE_KEYS = ("max_sides", "reinsert", "flip", "flat_delaunay_degrees", "fit_gain")


def decode_changes(section: dict[str, Any]) -> dict[str, Any]:
    """:class:`~spacemesh.decode.DecodeOptions` fields from a manifest's ``decode``
    section (:data:`DECODE_KEYS`; a repository written before a key existed keeps that
    field's default)."""
    return {key: section[key] for key in DECODE_KEYS if key in section}


@dataclass(frozen=True)
class ModelSpec:
    """What the pipeline needs to know about a model besides its networks.

    Attributes
    ----------
    n_points : int
        Encoder points.
    max_vertices : int
        Vertex tokens of the diffusion.
    normals : bool
        Whether the encoder reads normals (then every request must bring them).
    schedule : NoiseSchedule
        The trained schedule.
    method : str
        Default sampler (``ddim`` or ``ddpm``).
    steps : int
        Default sampler steps.
    decode : DecodeOptions
        How embeddings are read.
    vertex_spacing : float
        Sampled vertices closer than this (in the normalised [-1, 1] frame) to an
        earlier one are dropped before the connectivity network runs. Diffusion places
        vertices in clumps (median nearest-neighbour distance half the ground truth's on
        the ``small`` model), and a clump of near-duplicates cannot be joined into
        manifold faces, so the decode would have to drop them and their neighbours.
        Calibrated on the training set's val split at export
        (:func:`spacemesh.export.repository.calibrate_vertex_spacing`);
        ``manifest["sampler"]["vertex_spacing"]``, default :data:`DUPLICATE_TOLERANCE`.
    """

    n_points: int
    max_vertices: int
    normals: bool
    schedule: NoiseSchedule
    method: str
    steps: int
    decode: DecodeOptions
    vertex_spacing: float = DUPLICATE_TOLERANCE

    @classmethod
    def from_config(cls, config: dict[str, Any], betas: Sequence[float] | None = None,
                    reduction_params: dict[str, Any] | None = None) -> ModelSpec:
        """From a :class:`spacemesh.nn.config.ModelConfig` dict.

        Parameters
        ----------
        config : dict
        betas : sequence of float, optional
            The trained schedule (recomputed from the config when None).
        reduction_params : dict, optional
            Weights of a ``concat`` permutation reduction.

        Returns
        -------
        ModelSpec
        """
        diffusion = config["diffusion"]
        con = config["connectivity"]
        schedule = (
            NoiseSchedule(np.asarray(betas, dtype=np.float64)) if betas is not None
            else NoiseSchedule.from_config(diffusion["schedule"], diffusion["timesteps"])
        )
        params = (
            {k: np.asarray(v, np.float64) for k, v in reduction_params.items()}
            if reduction_params else None
        )
        return cls(
            n_points=int(config["encoder"]["n_points"]),
            max_vertices=int(config["max_vertices"]),
            normals=bool(config["encoder"]["normals"]),
            schedule=schedule,
            method=str(diffusion["sampler"]),
            steps=int(diffusion["steps"]),
            decode=DecodeOptions(distance=con["distance"], n_space=int(con["n_space"]),
                                 reduction=con["reduction"], reduction_params=params),
        )

    @classmethod
    def from_manifest(cls, manifest: dict[str, Any]) -> ModelSpec:
        """From a model repository's ``manifest.json``."""
        spec = cls.from_config(
            manifest["config"], manifest["schedule"]["betas"],
            manifest.get("embedding", {}).get("reduction_params"),
        )
        spacing = manifest.get("sampler", {}).get("vertex_spacing", DUPLICATE_TOLERANCE)
        decode = replace(spec.decode, **decode_changes(manifest.get("decode", {})))
        return replace(spec, vertex_spacing=float(spacing), decode=decode)


@dataclass(frozen=True)
class GenerateRequest:
    """One request of :meth:`MeshGenerator.generate_batch`.

    Attributes
    ----------
    points : (P, 3) float
        Conditioning points, any frame and scale.
    normals : (P, 3) float, optional
    seed : int
    steps : int, optional
        Sampler steps (the model's default when None).
    method : {"ddim", "ddpm"}, optional
        Sampler (the model's default when None).
    """

    points: FloatArray
    normals: FloatArray | None = None
    seed: int = 0
    steps: int | None = None
    method: str | None = None


@dataclass
class GenerateResult:
    """A generated mesh and how it was made.

    Attributes
    ----------
    mesh : PolygonMesh
        In the input's frame and scale, faces oriented outward.
    seed, steps : int
    method : str
    timings : dict of str to float
        Seconds spent in ``encoder``, ``sampler``, ``connectivity``, ``extraction`` and
        ``total``. For a batch, the network stages are the whole batch's times.
    n_sampled_vertices : int
        Tokens the mask channel kept, coincident ones merged (before the decode
        removed any).
    decode_stats : dict
        From :class:`spacemesh.decode.DecodeResult`.
    """

    mesh: PolygonMesh
    seed: int
    steps: int
    method: str
    timings: dict[str, float] = field(default_factory=dict)
    n_sampled_vertices: int = 0
    decode_stats: dict[str, Any] = field(default_factory=dict)


def normalize_points(points: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Centre the bounding box at the origin and scale the longest axis to [-1, 1].

    Parameters
    ----------
    points : (P, 3)

    Returns
    -------
    normalised : (P, 3) float64
    centre : (3,) float64
    scale : float
        ``points = normalised * scale + centre`` (1 for a single point).
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2.0
    scale = float((hi - lo).max()) / 2.0
    if not scale > 0:
        scale = 1.0
    return (points - centre) / scale, centre, scale


def choose_points(count: int, n_points: int, rng: np.random.Generator) -> IntArray:
    """Indices of ``n_points`` of ``count`` points: a random subset, or all plus repeats.

    Parameters
    ----------
    count, n_points : int
    rng : numpy.random.Generator

    Returns
    -------
    (n_points,) int64
    """
    if count >= n_points:
        return rng.choice(count, n_points, replace=False)
    extra = rng.choice(count, n_points - count, replace=True)
    return np.concatenate([np.arange(count), extra])


def check_points(points: Any, normals: Any = None) -> tuple[FloatArray, FloatArray | None]:
    """Validate a point cloud (and normals) and return them as float64 arrays.

    Raises
    ------
    ValueError
        Wrong shape, no points, or non-finite values.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (P, 3), not {p.shape}")
    if len(p) == 0:
        raise ValueError("the point cloud is empty")
    if not np.isfinite(p).all():
        raise ValueError("the point cloud has non-finite coordinates")
    if normals is None:
        return p, None
    n = np.asarray(normals, dtype=np.float64)
    if n.shape != p.shape:
        raise ValueError(f"normals must have the points' shape {p.shape}, not {n.shape}")
    if not np.isfinite(n).all():
        raise ValueError("the normals have non-finite values")
    return p, n


def drop_duplicates(positions: FloatArray, alive: np.ndarray,
                    tolerance: float = DUPLICATE_TOLERANCE) -> np.ndarray:
    """``alive`` without the later vertex of every pair closer than ``tolerance``.

    Parameters
    ----------
    positions : (N, 3)
    alive : (N,) bool
    tolerance : float

    Returns
    -------
    (N,) bool
    """
    from scipy.spatial import cKDTree

    alive = np.asarray(alive, dtype=bool).copy()
    index = np.flatnonzero(alive)
    if index.size < 2:
        return alive
    pairs = cKDTree(positions[index]).query_pairs(tolerance, output_type="ndarray")
    if len(pairs):
        alive[index[pairs.max(axis=1)]] = False
    return alive


def flip_faces(mesh: PolygonMesh) -> PolygonMesh:
    """The same mesh with every face's orientation reversed."""
    start = np.repeat(mesh.face_offsets[:-1], mesh.face_sizes)
    end = np.repeat(mesh.face_offsets[1:], mesh.face_sizes)
    position = np.arange(mesh.face_indices.size)
    reversed_indices = mesh.face_indices[start + end - 1 - position]
    return PolygonMesh(mesh.vertices, reversed_indices, mesh.face_offsets)


class MeshGenerator:
    """Generates meshes from point clouds with one model.

    Parameters
    ----------
    backend : Backend
        The three networks (onnxruntime, or torch for comparisons).
    spec : ModelSpec
    name : str
        Reported by the service.
    """

    def __init__(self, backend: Backend, spec: ModelSpec, *, name: str = "spacemesh") -> None:
        self.backend = backend
        self.spec = spec
        self.name = name
        self.repository = None  # set by from_repository

    @classmethod
    def from_repository(
        cls, path: str | Path | None = None, *, intra_op_threads: int = 0,
        inter_op_threads: int = 1,
    ) -> MeshGenerator:
        """Load a model repository (default: the shipped model) into a generator.

        Parameters
        ----------
        path : path, optional
            See :meth:`spacemesh.runtime.repository.ModelRepository.load`.
        intra_op_threads, inter_op_threads : int
            onnxruntime thread counts.

        Returns
        -------
        MeshGenerator
        """
        from spacemesh.runtime.repository import ModelRepository

        repo = ModelRepository.load(
            path, intra_op_threads=intra_op_threads, inter_op_threads=inter_op_threads
        )
        generator = cls(repo.backend, ModelSpec.from_manifest(repo.manifest), name=repo.name)
        generator.repository = repo
        return generator

    # ------------------------------------------------------------------ public API
    def generate(
        self,
        points: FloatArray,
        normals: FloatArray | None = None,
        *,
        seed: int = 0,
        steps: int | None = None,
        method: str | None = None,
        progress: ProgressFn | None = None,
    ) -> GenerateResult:
        """Generate one mesh.

        Parameters
        ----------
        points : (P, 3) float
            Conditioning points in any frame and scale.
        normals : (P, 3) float, optional
            Needed only by models whose encoder reads normals.
        seed : int
            The same seed gives the same mesh.
        steps : int, optional
            Sampler steps (default: the model's).
        method : {"ddim", "ddpm"}, optional
            Sampler (default: the model's).
        progress : callable, optional
            ``progress(done, total)`` after each denoiser step.

        Returns
        -------
        GenerateResult
        """
        request = GenerateRequest(points, normals, seed, steps, method)
        return self.generate_batch([request], progress=progress)[0]

    def generate_batch(
        self, requests: Sequence[GenerateRequest], *, progress: ProgressFn | None = None
    ) -> list[GenerateResult]:
        """Generate several meshes, sharing each network call.

        Requests with different ``steps``/``method`` run as separate groups.

        Parameters
        ----------
        requests : sequence of GenerateRequest
        progress : callable, optional
            ``progress(done, total)`` over the denoiser steps of all groups.

        Returns
        -------
        list of GenerateResult
            In request order.
        """
        groups: dict[tuple[int, str], list[int]] = {}
        for i, r in enumerate(requests):
            groups.setdefault(self._sampler_key(r), []).append(i)
        total = sum(k[0] for k in groups)
        results: list[GenerateResult | None] = [None] * len(requests)
        done = 0
        for key, members in groups.items():
            def report(step: int, _total: int, offset: int = done) -> None:
                if progress is not None:
                    progress(offset + step, total)

            batch = self._run_group([requests[i] for i in members], *key, report)
            for i, result in zip(members, batch, strict=True):
                results[i] = result
            done += key[0]
        return [r for r in results if r is not None]

    # ------------------------------------------------------------------ stages
    def _sampler_key(self, request: GenerateRequest) -> tuple[int, str]:
        steps = self.spec.steps if request.steps is None else int(request.steps)
        method = self.spec.method if request.method is None else str(request.method)
        if method not in METHODS:
            raise ValueError(f"unknown sampler {method!r}; choose from {', '.join(METHODS)}")
        if not 1 <= steps <= self.spec.schedule.timesteps:
            raise ValueError(f"steps must be in 1..{self.spec.schedule.timesteps}, not {steps}")
        return steps, method

    def prepare_points(
        self, points: FloatArray, normals: FloatArray | None
    ) -> tuple[np.ndarray, FloatArray, float]:
        """Encoder input ``(n_points, 3 or 6)`` float32 and the normalisation transform."""
        p, n = check_points(points, normals)
        if self.spec.normals and n is None:
            raise ValueError("this model needs normals with the points")
        unit, centre, scale = normalize_points(p)
        rng = np.random.default_rng(POINT_SUBSET_SEED)
        pick = choose_points(len(unit), self.spec.n_points, rng)
        columns = [unit[pick]]
        if self.spec.normals:
            length = np.linalg.norm(n, axis=1, keepdims=True)
            columns.append((n / np.where(length > 0, length, 1.0))[pick])
        return np.concatenate(columns, axis=1).astype(np.float32), centre, scale

    def _run_group(
        self, requests: list[GenerateRequest], steps: int, method: str, progress: ProgressFn
    ) -> list[GenerateResult]:
        t0 = time.perf_counter()
        prepared = [self.prepare_points(r.points, r.normals) for r in requests]
        points = np.stack([p[0] for p in prepared])  # (B, P, C)
        volumes = self.backend.encode(points)
        t1 = time.perf_counter()
        tokens = sample(
            lambda x, t: self.backend.denoise(x, t, volumes),
            seeds=[r.seed for r in requests], n_vertices=self.spec.max_vertices,
            steps=self.spec.schedule.respaced(steps), method=method, progress=progress,
        )
        positions, alive = split_tokens(tokens)  # (B, N, 3), (B, N)
        spacing = self.spec.vertex_spacing
        alive = np.stack([drop_duplicates(p, a, spacing)
                          for p, a in zip(positions, alive, strict=True)])
        t2 = time.perf_counter()
        emb = self.backend.connect(positions, alive, volumes)
        t3 = time.perf_counter()
        results = []
        for b, (request, (cloud, centre, scale)) in enumerate(
                zip(requests, prepared, strict=True)):
            e0 = time.perf_counter()
            embeddings = Embeddings(
                np.asarray(emb.x[b], np.float64), emb.tau, np.asarray(emb.root[b], np.float64),
                np.asarray(emb.prev[b], np.float64), np.asarray(emb.next[b], np.float64),
            )
            decoded = decode(positions[b].astype(np.float64), embeddings, self.spec.decode,
                             alive=alive[b], points=cloud[:, :3])
            mesh = decoded.mesh
            if mesh.n_faces and signed_volume(mesh) < 0:
                mesh = flip_faces(mesh)
            mesh = mesh.with_vertices(mesh.vertices * scale + centre)
            extraction = time.perf_counter() - e0
            timings = {"encoder": t1 - t0, "sampler": t2 - t1, "connectivity": t3 - t2,
                       "extraction": extraction}
            timings["total"] = sum(timings.values())
            results.append(GenerateResult(
                mesh=mesh, seed=int(request.seed), steps=steps, method=method, timings=timings,
                n_sampled_vertices=int(alive[b].sum()), decode_stats=dict(decoded.stats),
            ))
        return results
