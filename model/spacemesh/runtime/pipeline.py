"""Point cloud in, oriented manifold polygon mesh out: the full generation pipeline.

For each request:

1. set the outliers aside and measure the noise (:mod:`spacemesh.geometry.cleaning`),
   then normalise the rest (bounding-box centre to the origin, longest axis to [-1, 1]);
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
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from spacemesh.decode import DecodeOptions, DecodeResult, Embeddings, decode
from spacemesh.geometry import (
    FitReport,
    GeometryOptions,
    farthest_point_sampling,
    feature_weights,
    fit_report,
)
from spacemesh.geometry.cleaning import PointsQuality, assess_points
from spacemesh.geometry.policy import decode_changes
from spacemesh.geometry.untangle import untangle
from spacemesh.io.reduce import reduction_indices
from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.backend import Backend, ConnectivityOutputs, denoiser_fn
from spacemesh.runtime.finishing import finish_geometry, outward
from spacemesh.runtime.large import (
    DEFAULT_LARGE_MESHES,
    check_large_meshes,
    needs_split,
    network_vertices,
)
from spacemesh.runtime.options import MAX_RETRY_SEEDS, GenerateOptions
from spacemesh.runtime.pieces import point_pieces
from spacemesh.runtime.sampler import ProgressFn, StageFn, sample, split_tokens
from spacemesh.runtime.schedule import NoiseSchedule
from spacemesh.runtime.tolerance import aim, attempt_options, distance_of, search_vertex_count
from spacemesh.typed import FloatArray, IntArray

if TYPE_CHECKING:
    from spacemesh.runtime.repository import ModelRepository

#: Seed of the fixed generator that picks the encoder's points from a larger cloud.
POINT_SUBSET_SEED = 0

#: Sampled vertices closer than this (normalised units) are one vertex: coincident
#: vertices (e.g. two tokens clipped to the same corner of the cube) would give the
#: connectivity network identical inputs, hence exact ties in the decode.
DUPLICATE_TOLERANCE = 1e-4

#: Vertices ``start=points`` chooses when the request sets no ``target_vertices`` and the
#: manifest no ``sampler.vertices``.
DEFAULT_VERTICES = 200

#: Input points the geometry stage fits to at most (a fixed subset of larger clouds).
MAX_FIT_POINTS = 4096


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
    start : {"noise", "points"}
        Default vertex start (``manifest["sampler"]["start"]``; ``noise`` for models
        whose manifest predates it).
    start_time : float
        Default start time of ``start=points`` (``manifest["sampler"]["start_time"]``).
    vertices : int
        Vertices ``start=points`` chooses without ``target_vertices``
        (``manifest["sampler"]["vertices"]``).
    feature_boost : float
        Farthest-point sampling treats points on sharp features as this much farther
        away (1 + boost; :func:`spacemesh.geometry.sampling.feature_weights`), so
        creases and corners get denser vertices (``manifest["sampler"]["feature_boost"]``).
    geometry : GeometryOptions
        The geometry stage (``manifest["geometry"]`` overrides the defaults).
    local_points : int
        Nearest input points a local-point denoiser reads (0: none; it then also takes
        the encoder's input, see :func:`spacemesh.runtime.backend.denoiser_fn`).
    large_meshes : {"tokens", "split"}
        How ``start=points`` makes more vertices than ``max_vertices``: all of them as
        tokens of the connectivity network (up to a cap), or ``max_vertices`` tokens and
        edge splits (:mod:`spacemesh.runtime.large`; ``manifest["sampler"]["large_meshes"]``).
    retry_seeds : int
        Seeds tried beyond a request's own when none of its meshes has as many pieces as
        the points and faces that do not cross (``manifest["sampler"]["retry_seeds"]``, at
        most :data:`~spacemesh.runtime.options.MAX_RETRY_SEEDS`; 0, the default, tries
        none). The decode's topology and crossings depend on the seed; see
        docs/GEOMETRY.md.
    """

    n_points: int
    max_vertices: int
    normals: bool
    schedule: NoiseSchedule
    method: str
    steps: int
    decode: DecodeOptions
    vertex_spacing: float = DUPLICATE_TOLERANCE
    start: str = "noise"
    start_time: float = 0.0
    vertices: int = DEFAULT_VERTICES
    feature_boost: float = 0.0
    geometry: GeometryOptions = field(default_factory=GeometryOptions)
    local_points: int = 0
    large_meshes: str = DEFAULT_LARGE_MESHES
    retry_seeds: int = 0

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
        params: dict[str, FloatArray] | None = (
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
            local_points=int(config["denoiser"].get("local_points", 0)),
        )

    @classmethod
    def from_manifest(cls, manifest: dict[str, Any]) -> ModelSpec:
        """From a model repository's ``manifest.json``."""
        spec = cls.from_config(
            manifest["config"], manifest["schedule"]["betas"],
            manifest.get("embedding", {}).get("reduction_params"),
        )
        sampler = manifest.get("sampler", {})
        decode = replace(spec.decode, **decode_changes(manifest.get("decode", {})))
        return replace(
            spec, vertex_spacing=float(sampler.get("vertex_spacing", DUPLICATE_TOLERANCE)),
            decode=decode, start=str(sampler.get("start", "noise")),
            start_time=float(sampler.get("start_time", 0.0)),
            vertices=int(sampler.get("vertices", DEFAULT_VERTICES)),
            feature_boost=float(sampler.get("feature_boost", 0.0)),
            geometry=GeometryOptions.from_section(manifest.get("geometry", {})),
            large_meshes=check_large_meshes(
                str(sampler.get("large_meshes", DEFAULT_LARGE_MESHES))),
            retry_seeds=check_retry_seeds(sampler.get("retry_seeds", 0)),
        )


@dataclass(frozen=True)
class GenerateRequest:
    """One request of :meth:`MeshGenerator.generate_batch`.

    Attributes
    ----------
    points : (P, 3) float
        Conditioning points, any frame and scale.
    normals : (P, 3) float, optional
    options : GenerateOptions
        As the user sent them (resolved against the model by the generator).
    """

    points: FloatArray
    normals: FloatArray | None = None
    options: GenerateOptions = field(default_factory=GenerateOptions)


@dataclass
class GenerateResult:
    """A generated mesh and how it was made.

    Attributes
    ----------
    mesh : PolygonMesh
        In the input's frame and scale, faces oriented outward.
    options : GenerateOptions
        Resolved (the model's defaults filled in); ``options.seed`` is the seed of this
        mesh (with ``samples > 1``, the winner's).
    timings : dict of str to float
        Seconds spent in ``encoder``, ``sampler``, ``connectivity``, ``extraction``
        (decode), ``geometry``, ``report`` and ``total``. For a batch, the network
        stages are the whole batch's times.
    n_sampled_vertices : int
        Vertices given to the connectivity network (before the decode removed any).
    decode_stats : dict
        From :class:`spacemesh.decode.DecodeResult`.
    geometry_stats : dict
        From :class:`spacemesh.geometry.GeometryResult` (empty with ``raw``).
    fit : FitReport
        How well the mesh fits the uploaded points.
    sample_scores : list of (int, float)
        ``(seed, fit score)`` of every seed tried, in seed order.
    tolerance_tries : list of (int, float)
        With ``tolerance``: every vertex count the search tried and its
        ``points_to_mesh_mean_rel``, in order (:mod:`spacemesh.runtime.tolerance`).
    """

    mesh: PolygonMesh
    options: GenerateOptions
    timings: dict[str, float] = field(default_factory=dict)
    n_sampled_vertices: int = 0
    decode_stats: dict[str, Any] = field(default_factory=dict)
    geometry_stats: dict[str, Any] = field(default_factory=dict)
    fit: FitReport | None = None
    sample_scores: list[tuple[int, float]] = field(default_factory=list)
    tolerance_tries: list[tuple[int, float]] = field(default_factory=list)

    @property
    def seed(self) -> int:
        """The seed of this mesh."""
        return int(self.options.seed)

    @property
    def steps(self) -> int:
        """Sampler steps of the whole schedule."""
        return int(self.options.steps or 0)

    @property
    def method(self) -> str:
        """The sampler."""
        return str(self.options.sampler)


@dataclass(frozen=True)
class PreparedInput:
    """One request's points, checked and normalised once and shared by its seeds.

    Attributes
    ----------
    cloud : (n_points, 3 or 6) float32
        Encoder input.
    centre : (3,) float
    scale : float
        ``points = unit * scale + centre``.
    points : (P, 3) float64
        The uploaded points that are not outliers (the fit report's reference).
    unit : (P, 3) float64
        The same, normalised.
    normals : (P, 3) float64, optional
        The upload's normals of those points.
    weights : (P,) float64, optional
        Farthest-point weights (``start=points`` only).
    quality : PointsQuality
        The outliers set aside and the noise of the rest (:func:`assess_points`; its
        ``kept`` mask is over the upload's points).
    pieces : int
        The pieces the points form (:func:`point_pieces` of the encoder's cloud), made
        once on first use and shared by the request's seeds and tolerance tries.
    """

    cloud: np.ndarray
    centre: FloatArray
    scale: float
    points: FloatArray
    unit: FloatArray
    normals: FloatArray | None
    weights: FloatArray | None
    quality: PointsQuality

    def report(self, mesh: PolygonMesh) -> FitReport:
        """The fit report of ``mesh`` (in the upload's frame) against these points, with
        the points' noise and outlier share."""
        return replace(fit_report(mesh, self.points), points_noise=self.quality.noise,
                       points_outliers=self.quality.outliers)

    @cached_property
    def pieces(self) -> int:
        """The pieces the points form (made once; see the attributes)."""
        return point_pieces(self.cloud[:, :3])

    def fit_points(self) -> tuple[FloatArray, FloatArray | None]:
        """The normalised points (and normals) the geometry stage fits to, at most
        :data:`MAX_FIT_POINTS` of them (a fixed subset)."""
        pick = reduction_indices(len(self.unit), MAX_FIT_POINTS, seed=POINT_SUBSET_SEED)
        if pick is None:
            return self.unit, self.normals
        return self.unit[pick], None if self.normals is None else self.normals[pick]


def check_retry_seeds(value: Any) -> int:
    """A manifest's ``sampler.retry_seeds``, checked (0 to :data:`MAX_RETRY_SEEDS`)."""
    if isinstance(value, bool) or not isinstance(value, int) or not (
            0 <= value <= MAX_RETRY_SEEDS):
        raise ValueError(f"sampler.retry_seeds must be an integer from 0 to "
                         f"{MAX_RETRY_SEEDS}, not {value!r}")
    return value


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
        self.repository: ModelRepository | None = None  # set by from_repository

    @classmethod
    def from_repository(
        cls, path: str | Path | None = None, *, threads: int = 0,
    ) -> MeshGenerator:
        """Load a model repository (default: the shipped model) into a generator.

        Parameters
        ----------
        path : path, optional
            See :meth:`spacemesh.runtime.repository.ModelRepository.load`.
        threads : int
            Threads that run the networks' batch items at once (0: one per core); the
            meshes do not depend on it (:class:`~spacemesh.runtime.backend.OnnxBackend`).

        Returns
        -------
        MeshGenerator
        """
        from spacemesh.runtime.repository import ModelRepository

        repo = ModelRepository.load(path, threads=threads)
        generator = cls(repo.backend, ModelSpec.from_manifest(repo.manifest), name=repo.name)
        generator.repository = repo
        return generator

    # ------------------------------------------------------------------ public API
    def generate(
        self,
        points: FloatArray,
        normals: FloatArray | None = None,
        options: GenerateOptions | None = None,
        *,
        progress: ProgressFn | None = None,
        stage: StageFn | None = None,
        **fields: Any,
    ) -> GenerateResult:
        """Generate one mesh.

        Parameters
        ----------
        points : (P, 3) float
            Conditioning points in any frame and scale.
        normals : (P, 3) float, optional
            Used by the geometry stage (estimated when absent), and needed by models
            whose encoder reads normals.
        options : GenerateOptions, optional
            Default: the model's defaults with seed 0.
        progress : callable, optional
            ``progress(done, total)`` after each denoiser step.
        stage : callable, optional
            ``stage(name, done, total)`` as each stage begins (see
            :meth:`generate_batch`).
        **fields
            :class:`~spacemesh.runtime.options.GenerateOptions` fields by name (e.g.
            ``seed=3, raw=True``), applied over ``options``.

        Returns
        -------
        GenerateResult

        Raises
        ------
        OptionError
            An option out of range.
        ValueError
            Points (or normals) that cannot be used.
        """
        options = replace(options or GenerateOptions(), **fields)
        request = GenerateRequest(points, normals, options)
        return self.generate_batch([request], progress=progress, stage=stage)[0]

    def generate_batch(
        self, requests: Sequence[GenerateRequest], *, progress: ProgressFn | None = None,
        stage: StageFn | None = None,
    ) -> list[GenerateResult]:
        """Generate several meshes, sharing each network call.

        Requests with different sampler settings (steps, sampler, start, start time)
        run as separate groups; a request with ``samples = K`` runs its K seeds in its
        group and keeps the best-fitting mesh. A request with a ``tolerance`` runs on
        its own, after the others, as a search over vertex counts
        (:mod:`spacemesh.runtime.tolerance`; its stage events include ``tolerance``,
        the ``done``-th of at most ``total`` tries).

        Parameters
        ----------
        requests : sequence of GenerateRequest
        progress : callable, optional
            ``progress(done, total)`` over the denoiser steps of all groups.
        stage : callable, optional
            ``stage(name, done, total)`` as each stage begins: ``encoder``, ``sampler``
            (0 of its ``total`` denoiser steps done; ``progress`` follows), then ``decode``,
            ``geometry`` (not with ``raw``) and ``report`` for the ``done``-th of
            ``total`` meshes of the group (a request with ``samples = K`` makes K).
            Reporting never changes a result.

        Returns
        -------
        list of GenerateResult
            In request order.

        Raises
        ------
        OptionError
            An option out of range (before any network runs).
        """
        resolved = [r.options.resolve(self.spec) for r in requests]
        # each request's points once, shared by its seeds and tries (fails before any work)
        inputs = [self.prepare_input(r, o) for r, o in zip(requests, resolved, strict=True)]
        plain = [i for i, options in enumerate(resolved) if options.tolerance is None]
        found = self._generate_prepared([(inputs[i], resolved[i]) for i in plain],
                                        progress, stage)
        results: list[GenerateResult | None] = [None] * len(requests)
        for index, result in zip(plain, found, strict=True):
            results[index] = result
        for index, options in enumerate(resolved):
            if options.tolerance is not None:  # searched after the others
                results[index] = self._within_tolerance(inputs[index], options, progress,
                                                        stage)
        return [result for result in results if result is not None]

    def _generate_prepared(
        self, items: Sequence[tuple[PreparedInput, GenerateOptions]],
        progress: ProgressFn | None, stage: StageFn | None, *, retry: bool = True,
    ) -> list[GenerateResult]:
        """:meth:`generate_batch` on prepared inputs with resolved options (no
        ``tolerance``): the best fit of each request's seeds, in request order.

        With a model whose :attr:`ModelSpec.retry_seeds` is set, a mesh with as many
        pieces as the points (:func:`point_pieces`) is preferred to any without, then
        one whose faces do not cross; when none of a request's seeds has both, that many
        more seeds run (stage ``pieces``; not with ``retry`` False) before choosing
        (:func:`_best_fit`).
        """
        results = []
        for (prepared, options), tried in zip(items, self._seed_results(items, progress,
                                                                         stage), strict=True):
            expected = prepared.pieces
            if (retry and self.spec.retry_seeds and not options.raw
                    and not any(_acceptable(r, expected) for r in tried)):
                tried += self._retry_seeds(prepared, options, progress, stage)
            chosen = _best_fit(tried, options, expected, check=self.spec.retry_seeds > 0)
            results.append(self._untangled(chosen, prepared, stage))
        return results

    def _untangled(self, result: GenerateResult, prepared: PreparedInput,
                   stage: StageFn | None) -> GenerateResult:
        """With the model's topology check on (:attr:`ModelSpec.retry_seeds`), the
        chosen mesh's crossing faces smoothed apart (:func:`untangle`, stage
        ``untangle``), fitted to the points again (:func:`finish_geometry`, whose guard
        lets no face cross that the untangling freed; smoothing alone can pull a folded
        mesh far from the points) and its fit report made again; ``raw`` results are
        left alone."""
        if (not self.spec.retry_seeds or result.options.raw or result.fit is None
                or not _crosses(result)):
            return result
        if stage is not None:
            stage("untangle", 1, 1)
        mesh, stats = untangle(result.mesh)
        if stats["crossing_after"] >= stats["crossing_before"]:
            return result
        unit = mesh.with_vertices((mesh.vertices - prepared.centre) / prepared.scale)
        points, normals = prepared.fit_points()
        refitted, refit_stats = finish_geometry(unit, points, normals, self.spec.geometry)
        mesh = refitted.with_vertices(refitted.vertices * prepared.scale + prepared.centre)
        stats["untangle_refit_kept"] = bool(refit_stats.get("kept", False))
        result.mesh = mesh
        result.geometry_stats = {**result.geometry_stats, **stats}
        result.fit = replace(prepared.report(mesh),
                             points_pieces=result.fit.points_pieces,
                             tolerance=result.fit.tolerance,
                             tolerance_met=result.fit.tolerance_met)
        return result

    def _retry_seeds(self, prepared: PreparedInput, options: GenerateOptions,
                     progress: ProgressFn | None, stage: StageFn | None
                     ) -> list[GenerateResult]:
        """The results of the model's ``retry_seeds`` seeds after a request's own
        (stage ``pieces``)."""
        if stage is not None:
            stage("pieces", 1, 1)
        more = replace(options, seed=options.seed + options.samples,
                       samples=self.spec.retry_seeds)
        return self._seed_results([(prepared, more)], progress, stage)[0]

    def _seed_results(
        self, items: Sequence[tuple[PreparedInput, GenerateOptions]],
        progress: ProgressFn | None, stage: StageFn | None,
    ) -> list[list[GenerateResult]]:
        """Every seed's result of each request (``samples`` seeds from its ``seed``),
        the seeds of all requests grouped by sampler settings to share network calls."""
        jobs: list[tuple[int, GenerateOptions]] = []  # (request index, one seed)
        for index, (_, options) in enumerate(items):
            jobs += [(index, replace(options, seed=options.seed + k))
                     for k in range(options.samples)]
        groups: dict[tuple[int, str, str, float], list[int]] = {}
        for j, (_, options) in enumerate(jobs):
            groups.setdefault(self._sampler_key(options), []).append(j)
        total = sum(self._denoiser_steps(key) for key in groups)
        outcomes: list[GenerateResult | None] = [None] * len(jobs)
        done = 0
        for key, members in groups.items():
            def report(step: int, _total: int, offset: int = done) -> None:
                if progress is not None:
                    progress(offset + step, total)

            batch = self._run_group([(items[jobs[j][0]][0], jobs[j][1]) for j in members],
                                    key, report, stage or _no_stage)
            for j, result in zip(members, batch, strict=True):
                outcomes[j] = result
            done += self._denoiser_steps(key)
        return [[r for j, (i, _) in enumerate(jobs) if i == index
                 for r in [outcomes[j]] if r is not None] for index in range(len(items))]

    def _within_tolerance(self, prepared: PreparedInput, options: GenerateOptions,
                          progress: ProgressFn | None, stage: StageFn | None
                          ) -> GenerateResult:
        """The smallest mesh within ``options.tolerance`` (resolved options), every try
        on the same prepared points. The tries run without the model's retry seeds (the
        search's time); the count found gets them when its mesh fails the topology
        check, and a retry's mesh is taken only if it keeps the tolerance met."""
        assert options.tolerance is not None
        tolerance = float(options.tolerance)

        def run(count: int) -> GenerateResult:
            attempt = attempt_options(options, count).resolve(self.spec)  # checks the count
            return self._generate_prepared([(prepared, attempt)], progress, stage,
                                           retry=False)[0]

        def on_try(done: int, total: int) -> None:
            if stage is not None:
                stage("tolerance", done, total)

        found, _, tried = search_vertex_count(run, aim(tolerance), self.vertex_count(options),
                                              on_try=on_try)
        expected = prepared.pieces
        if self.spec.retry_seeds and not _acceptable(found, expected):
            keep_met = distance_of(found) <= tolerance
            extra = [r for r in self._retry_seeds(prepared, found.options, progress, stage)
                     if distance_of(r) <= tolerance or not keep_met]
            found = _best_fit([found, *extra], found.options, expected)
        found = self._untangled(found, prepared, stage)
        met = distance_of(found) <= tolerance
        found.options = replace(found.options, tolerance=tolerance, target_vertices=None)
        if found.fit is not None:
            found.fit = replace(found.fit, tolerance=tolerance, tolerance_met=met)
        found.tolerance_tries = tried
        return found

    # ------------------------------------------------------------------ stages
    @staticmethod
    def _sampler_key(options: GenerateOptions) -> tuple[int, str, str, float]:
        start_time = 1.0 if options.start_time is None else float(options.start_time)
        assert options.steps is not None  # resolved options (GenerateOptions.resolve)
        return int(options.steps), str(options.sampler), str(options.start), start_time

    def _denoiser_steps(self, key: tuple[int, str, str, float]) -> int:
        from spacemesh.runtime.sampler import start_steps

        steps, _, start, start_time = key
        respaced = self.spec.schedule.respaced(steps)
        return len(respaced) if start == "noise" else start_steps(respaced, start_time)

    def prepare_points(
        self, points: FloatArray, normals: FloatArray | None
    ) -> tuple[np.ndarray, FloatArray, float]:
        """Encoder input ``(n_points, 3 or 6)`` float32 and the normalisation transform."""
        prepared = self.prepare_input(GenerateRequest(points, normals))
        return prepared.cloud, prepared.centre, prepared.scale

    def prepare_input(self, request: GenerateRequest,
                      options: GenerateOptions | None = None) -> PreparedInput:
        """A request's points checked, normalised and subsampled once for all its seeds.

        Parameters
        ----------
        request : GenerateRequest
        options : GenerateOptions, optional
            Resolved; with ``start=points`` the farthest-point weights are made too.

        Returns
        -------
        PreparedInput

        Raises
        ------
        ValueError
            Points (or normals) that cannot be used.
        """
        p, n = check_points(request.points, request.normals)
        if self.spec.normals and n is None:
            raise ValueError("this model needs normals with the points")
        quality = assess_points(p)
        if not quality.kept.all():
            p = p[quality.kept]
            n = None if n is None else n[quality.kept]
        unit, centre, scale = normalize_points(p)
        rng = np.random.default_rng(POINT_SUBSET_SEED)
        pick = choose_points(len(unit), self.spec.n_points, rng)
        columns = [unit[pick]]
        if self.spec.normals:
            assert n is not None  # checked above
            length = np.linalg.norm(n, axis=1, keepdims=True)
            columns.append((n / np.where(length > 0, length, 1.0))[pick])
        cloud = np.concatenate(columns, axis=1).astype(np.float32)
        weights = (feature_weights(unit, self.spec.feature_boost)
                   if options is not None and options.start == "points" else None)
        return PreparedInput(cloud, centre, scale, p, unit, n, weights, quality)

    def vertex_count(self, options: GenerateOptions) -> int:
        """Vertices ``start=points`` chooses: the target, else the model's default."""
        return int(options.target_vertices or self.spec.vertices)

    def _start_tokens(self, jobs: list[tuple[PreparedInput, GenerateOptions]]) -> np.ndarray:
        """Clean tokens ``(B, N, 4)`` of the farthest-point vertices of each job's
        normalised cloud (real tokens first, padding after with mask -1)."""
        chosen = []
        for prepared, options in jobs:
            wanted = network_vertices(self.vertex_count(options), self.spec.max_vertices,
                                      self.spec.large_meshes, raw=options.raw)
            pick = farthest_point_sampling(prepared.unit, wanted, seed=options.seed,
                                           weights=prepared.weights)
            chosen.append(prepared.unit[pick])
        n = max([self.spec.max_vertices, *(len(c) for c in chosen)])
        tokens = np.zeros((len(jobs), n, 4), dtype=np.float32)
        tokens[..., 3] = -1.0
        for b, c in enumerate(chosen):
            tokens[b, : len(c), :3] = c
            tokens[b, : len(c), 3] = 1.0
        return tokens

    def _decode(self, positions: np.ndarray, emb: ConnectivityOutputs, b: int,
                alive: np.ndarray, prepared: PreparedInput) -> DecodeResult:
        """Decode batch item ``b`` of the connectivity outputs ``emb`` (positions
        ``(N, 3)``, alive ``(N,)``)."""
        embeddings = Embeddings(
            np.asarray(emb.x[b], np.float64), emb.tau, np.asarray(emb.root[b], np.float64),
            np.asarray(emb.prev[b], np.float64), np.asarray(emb.next[b], np.float64),
        )
        return decode(positions.astype(np.float64), embeddings, self.spec.decode,
                      alive=alive, points=prepared.cloud[:, :3])

    def _run_group(
        self, jobs: list[tuple[PreparedInput, GenerateOptions]],
        key: tuple[int, str, str, float], progress: ProgressFn, stage: StageFn,
    ) -> list[GenerateResult]:
        steps, method, start, start_time = key
        stage("encoder", 1, 1)
        t0 = time.perf_counter()
        points = np.stack([prepared.cloud for prepared, _ in jobs])  # (B, P, C)
        volumes = self.backend.encode(points)
        t1 = time.perf_counter()
        clean = self._start_tokens(jobs) if start == "points" else None
        n_tokens = self.spec.max_vertices if clean is None else clean.shape[1]
        stage("sampler", 0, self._denoiser_steps(key))
        tokens = sample(
            denoiser_fn(self.backend, volumes, points if self.spec.local_points else None),
            seeds=[options.seed for _, options in jobs], n_vertices=n_tokens,
            steps=self.spec.schedule.respaced(steps), method=method, progress=progress,
            start=clean, start_time=start_time,
        )
        positions, alive = split_tokens(tokens)  # (B, N, 3), (B, N)
        spacing = self.spec.vertex_spacing if start == "noise" else DUPLICATE_TOLERANCE
        alive = np.stack([drop_duplicates(p, a, spacing)
                          for p, a in zip(positions, alive, strict=True)])
        t2 = time.perf_counter()
        stage("connectivity", 1, 1)
        emb = self.backend.connect(positions, alive, volumes)
        t3 = time.perf_counter()
        results = []
        for b, (prepared, options) in enumerate(jobs):
            stage("decode", b + 1, len(jobs))
            e0 = time.perf_counter()
            decoded = self._decode(positions[b], emb, b, alive[b], prepared)
            m = self.spec.max_vertices
            if (start == "points" and not options.raw
                    and needs_split(int(alive[b].sum()), decoded.mesh.n_vertices, m)):
                # the full-token graph fell apart: the model's own token count instead
                alive[b, m:] = False
                prefix = self.backend.connect(positions[b:b + 1, :m], alive[b:b + 1, :m],
                                              [v[b:b + 1] for v in volumes])
                decoded = self._decode(positions[b, :m], prefix, 0, alive[b, :m], prepared)
                decoded.stats["large_meshes"] = "split"
            mesh = outward(decoded.mesh)
            e1 = time.perf_counter()
            geometry_stats: dict[str, Any] = {}
            if not options.raw:
                stage("geometry", b + 1, len(jobs))
                unit, normals = prepared.fit_points()
                mesh, geometry_stats = finish_geometry(
                    mesh, unit, normals, self.spec.geometry,
                    target_vertices=self.vertex_count(options) if start == "points" else None,
                )
            mesh = mesh.with_vertices(mesh.vertices * prepared.scale + prepared.centre)
            e2 = time.perf_counter()
            stage("report", b + 1, len(jobs))
            report = prepared.report(mesh)
            timings = {"encoder": t1 - t0, "sampler": t2 - t1, "connectivity": t3 - t2,
                       "extraction": e1 - e0, "geometry": e2 - e1,
                       "report": time.perf_counter() - e2}
            timings["total"] = sum(timings.values())
            results.append(GenerateResult(
                mesh=mesh, options=options, timings=timings,
                n_sampled_vertices=int(alive[b].sum()), decode_stats=dict(decoded.stats),
                geometry_stats=geometry_stats, fit=report,
            ))
        return results


def _no_stage(name: str, done: int, total: int) -> None:
    """A :data:`~spacemesh.runtime.sampler.StageFn` that reports nowhere."""


def _pieces_agree(result: GenerateResult, expected: int) -> bool:
    """Whether ``result``'s mesh has ``expected`` pieces (the points' own count)."""
    return result.fit is not None and result.fit.pieces == expected


def _crosses(result: GenerateResult) -> bool:
    """Whether ``result``'s mesh has faces that intersect others (its fit report)."""
    return result.fit is None or result.fit.self_intersections != 0


def _acceptable(result: GenerateResult, expected: int) -> bool:
    """As many pieces as the points and no crossing faces: no other seed is needed."""
    return _pieces_agree(result, expected) and not _crosses(result)


def _best_fit(tried: list[GenerateResult], options: GenerateOptions,
              expected_pieces: int, *, check: bool = True) -> GenerateResult:
    """The result of the seed that fits best: with ``check``, one whose pieces agree
    with the points' ``expected_pieces`` first, then one without crossing faces; then
    the lowest fit score, then the lower seed. With every seed's score, the points'
    pieces and the request's resolved options at the winner's seed."""
    def score(result: GenerateResult) -> float:
        value = result.fit.score if result.fit is not None else float("nan")
        return value if np.isfinite(value) else float("inf")

    scores = [(r.seed, score(r)) for r in tried]
    def rank(i: int) -> tuple[bool, bool, float, int]:
        return (check and not _pieces_agree(tried[i], expected_pieces),
                check and _crosses(tried[i]), scores[i][1], scores[i][0])

    best = min(range(len(tried)), key=rank)
    winner = tried[best]
    winner.options = replace(options, seed=winner.seed)
    winner.sample_scores = scores
    if winner.fit is not None:
        winner.fit = replace(winner.fit, points_pieces=expected_pieces)
    return winner
