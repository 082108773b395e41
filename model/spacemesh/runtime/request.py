"""A generate request, its points prepared once for all its seeds, and its result.

:func:`prepare_input` checks a request's points, sets its outliers aside and measures
their noise (:mod:`spacemesh.geometry.cleaning`), normalises the rest (bounding-box
centre to the origin, longest axis to [-1, 1]) and picks the encoder's points from them
(a fixed seed, so deterministically): a :class:`PreparedInput`, shared by the request's
seeds and tolerance tries.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from spacemesh.geometry import FitReport, PointFacts, SurfaceFacts, feature_weights, fit_report
from spacemesh.geometry.cleaning import PointsQuality, assess_points
from spacemesh.geometry.pieces import point_pieces
from spacemesh.io.reduce import reduction_indices
from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.spec import ModelSpec
from spacemesh.typed import FloatArray, IntArray

#: Seed of the fixed generator that picks the encoder's points from a larger cloud.
POINT_SUBSET_SEED = 0

#: Input points the geometry stage fits to at most (a fixed subset of larger clouds).
MAX_FIT_POINTS = 4096


@dataclass(frozen=True)
class GenerateRequest:
    """One request of :meth:`spacemesh.runtime.MeshGenerator.generate_batch`.

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
        (decode), ``geometry``, ``report`` and ``total``, over everything the request
        ran: every seed (the model's retry seeds included), every tolerance try and the
        untangling (in ``geometry``). Network calls shared by a batch count a share each.
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
    decoded : PolygonMesh or None
        An open surface's closed decode, outward, in the normalised frame, before the
        geometry stage (:meth:`spacemesh.runtime.MeshGenerator` trims it first for a
        second candidate); None otherwise.
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
    decoded: PolygonMesh | None = field(default=None, repr=False)

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
    tolerance : float, optional
        A tolerance request's tolerance, which every fit report of the request carries.
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
    tolerance: float | None = None

    def report(self, mesh: PolygonMesh, surface: SurfaceFacts | None = None) -> FitReport:
        """The fit report of ``mesh`` (in the upload's frame) against these points, made
        once with everything the response says: the points' pieces, noise and outlier
        share, the request's tolerance and, once decided, its surface."""
        facts = PointFacts(self.pieces, self.quality.outliers, self.quality.noise)
        return fit_report(mesh, self.points, facts, self.tolerance, surface)

    @cached_property
    def pieces(self) -> int:
        """The pieces the points form (made once; see the attributes)."""
        return point_pieces(self.cloud[:, :3])

    def fit_points(self) -> tuple[FloatArray, FloatArray | None]:
        """The normalised points (and normals) the geometry stage fits to, at most
        :data:`MAX_FIT_POINTS` of them (a fixed subset, :meth:`fit_subset`)."""
        return (self.fit_subset(self.unit),
                None if self.normals is None else self.fit_subset(self.normals))

    def fit_subset(self, values: np.ndarray) -> np.ndarray:
        """The rows of ``values`` ((P, ...), one per kept point) of the fixed subset of
        at most :data:`MAX_FIT_POINTS` points the geometry stage fits to (all of them for
        a cloud that small)."""
        pick = reduction_indices(len(values), MAX_FIT_POINTS, seed=POINT_SUBSET_SEED)
        return values if pick is None else values[pick]

    def to_upload(self, mesh: PolygonMesh) -> PolygonMesh:
        """``mesh`` from the normalised frame into the upload's (``unit * scale +
        centre``)."""
        return mesh.with_vertices(mesh.vertices * self.scale + self.centre)

    def to_unit(self, mesh: PolygonMesh) -> PolygonMesh:
        """``mesh`` from the upload's frame into the normalised one."""
        return mesh.with_vertices((mesh.vertices - self.centre) / self.scale)



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



def summed_timings(results: list[GenerateResult]) -> dict[str, float]:
    """The stage times of ``results`` added up (what a request that ran them all spent).

    Parameters
    ----------
    results : list of GenerateResult

    Returns
    -------
    dict of str to float
        Each stage's seconds over all of them.
    """
    total: dict[str, float] = {}
    for result in results:
        for name, seconds in result.timings.items():
            total[name] = total.get(name, 0.0) + float(seconds)
    return total


def prepare_input(request: GenerateRequest, spec: ModelSpec,
                  options: GenerateOptions | None = None) -> PreparedInput:
    """A request's points checked, normalised and subsampled once for all its seeds.

    Parameters
    ----------
    request : GenerateRequest
    spec : ModelSpec
        The model's encoder count, normals and feature boost.
    options : GenerateOptions, optional
        Resolved; with ``start=points`` the farthest-point weights are made too, and a
        ``tolerance`` goes into every fit report.

    Returns
    -------
    PreparedInput

    Raises
    ------
    ValueError
        Points (or normals) that cannot be used.
    """
    p, n = check_points(request.points, request.normals)
    if spec.normals and n is None:
        raise ValueError("this model needs normals with the points")
    quality = assess_points(p)
    if not quality.kept.all():
        p = p[quality.kept]
        n = None if n is None else n[quality.kept]
    unit, centre, scale = normalize_points(p)
    rng = np.random.default_rng(POINT_SUBSET_SEED)
    pick = choose_points(len(unit), spec.n_points, rng)
    columns = [unit[pick]]
    if spec.normals:
        assert n is not None  # checked above
        length = np.linalg.norm(n, axis=1, keepdims=True)
        columns.append((n / np.where(length > 0, length, 1.0))[pick])
    cloud = np.concatenate(columns, axis=1).astype(np.float32)
    weights = (feature_weights(unit, spec.feature_boost)
               if options is not None and options.start == "points" else None)
    tolerance = None if options is None or options.tolerance is None else float(
        options.tolerance)
    return PreparedInput(cloud, centre, scale, p, unit, n, weights, quality, tolerance)


__all__ = ["MAX_FIT_POINTS", "POINT_SUBSET_SEED", "GenerateRequest", "GenerateResult",
           "PreparedInput", "check_points", "choose_points", "normalize_points",
           "prepare_input", "summed_timings"]
