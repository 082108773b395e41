"""How well a mesh fits the points it was made from: the fit report of every response.

One definition, used by the service's headers and JSON, gRPC stats, both command
lines and ``samples=K`` (which keeps the seed with the lowest :attr:`FitReport.score`):

* ``points_to_mesh_mean`` / ``_p95``: distance from the input points (all of them, up
  to :data:`MAX_REPORT_POINTS`, a fixed deterministic subset beyond) to the mesh;
* ``mesh_to_points_mean`` / ``_p95``: distance from :data:`MESH_SAMPLES` points spread
  over the mesh (area-weighted, fixed seed) to the nearest input point;
* each also as a fraction of the input's bounding-box diagonal (``*_rel``);
* ``coverage``: the share of input points within :data:`COVERAGE_FRACTION` of the
  diagonal from the mesh;
* ``components``: connected components of faces (faces sharing a vertex are connected);
* ``pieces``, ``genus``, ``boundary_loops``: the topology a user sees
  (:func:`spacemesh.topology.surface_topology`: pieces connected through shared edges
  after welding equal positions, their summed genus, the open rims);
* ``self_intersections``: the share of faces that intersect another face
  (:mod:`spacemesh.geometry.intersections`);
* ``tolerance`` and ``tolerance_met``: with a ``tolerance`` request only, the tolerance
  asked for and whether ``points_to_mesh_mean_rel`` reached it
  (:mod:`spacemesh.runtime.tolerance`);
* ``points_pieces``: from a generate, the pieces of the surface the points sample, the
  points' own estimate (:func:`spacemesh.geometry.pieces.point_pieces`, a
  :class:`PointFacts` field); the mesh's
  ``pieces`` agree with the points when the two are equal (:attr:`FitReport.pieces_agree`);
* ``points_outliers`` and ``points_noise``: from a generate, the share of the uploaded
  points set aside as outliers before anything else ran, and the noise of the rest
  along the surface normal as a fraction of their diagonal
  (:func:`spacemesh.geometry.cleaning.assess_points`). The distances above are measured
  from the kept points;
* ``face_planarity``: the largest distance of a face's corner from the face's best-fit
  plane, as a fraction of the diagonal (0 for triangles;
  :func:`spacemesh.geometry.polygons.face_planarity`);
* ``open_surface`` and ``unsupported_area``: from a generate (not ``raw``), whether the
  mesh was trimmed to its points (``surface=open``, or ``auto`` deciding so) and the
  share of the closed mesh's area that no point supports and no point lies in front
  of, the evidence ``auto`` decides on (:mod:`spacemesh.geometry.surface`,
  :class:`SurfaceFacts`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.geometry.intersections import self_intersection_fraction
from spacemesh.geometry.polygons import face_planarity
from spacemesh.io.reduce import reduction_indices
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangle_areas, triangles_of
from spacemesh.primitives.closest import mean_distance, nearest_triangles
from spacemesh.topology import surface_topology, vertex_connected_faces
from spacemesh.typed import FloatArray

#: Input points measured at most (a fixed subset of larger clouds).
MAX_REPORT_POINTS = 20_000
#: Points spread over the mesh for the mesh -> points distances.
MESH_SAMPLES = 4096
#: Coverage threshold, as a fraction of the bounding-box diagonal.
COVERAGE_FRACTION = 0.01
#: Seed of the report's subsets and samples (the report is deterministic).
REPORT_SEED = 0


#: Fields of :class:`FitReport` that only some responses have (left out when None).
_OPTIONAL = ("tolerance", "tolerance_met", "points_pieces", "points_outliers", "points_noise",
             "open_surface", "unsupported_area")


@dataclass(frozen=True)
class FitReport:
    """Distances between a mesh and its input points (see the module docstring).

    Distances are in the input's units; ``*_rel`` ones are fractions of ``diagonal``.
    """

    points_to_mesh_mean: float
    points_to_mesh_p95: float
    mesh_to_points_mean: float
    mesh_to_points_p95: float
    points_to_mesh_mean_rel: float
    points_to_mesh_p95_rel: float
    mesh_to_points_mean_rel: float
    mesh_to_points_p95_rel: float
    coverage: float
    components: int
    self_intersections: float
    diagonal: float
    n_points: int
    pieces: int
    genus: int
    boundary_loops: int
    tolerance: float | None = None
    tolerance_met: bool | None = None
    points_pieces: int | None = None
    points_outliers: float | None = None
    points_noise: float | None = None
    open_surface: bool | None = None
    unsupported_area: float | None = None
    face_planarity: float = 0.0

    @property
    def pieces_agree(self) -> bool | None:
        """Whether the mesh has as many pieces as the points (None without the points'
        estimate)."""
        return None if self.points_pieces is None else self.pieces == self.points_pieces

    @property
    def score(self) -> float:
        """Lower is better: the two mean distances summed, relative to the diagonal
        (:func:`fit_score` computes it alone)."""
        return self.points_to_mesh_mean_rel + self.mesh_to_points_mean_rel

    def to_dict(self) -> dict[str, float | int]:
        """Every field by name (``tolerance``, ``tolerance_met``, ``points_pieces``,
        ``points_outliers``, ``points_noise``, ``open_surface`` and
        ``unsupported_area`` only when set)."""
        return {k: v for k, v in asdict(self).items() if v is not None or k not in _OPTIONAL}


def _surface_samples(vertices: FloatArray, triangles: np.ndarray, count: int) -> FloatArray:
    corners = vertices[triangles]  # (T, 3, 3)
    area = triangle_areas(vertices, triangles)  # (T,)
    rng = np.random.default_rng(REPORT_SEED)
    weights = area / area.sum() if area.sum() > 0 else None
    pick = rng.choice(len(triangles), count, p=weights)
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    c = corners[pick]
    return c[:, 0] + u[:, None] * (c[:, 1] - c[:, 0]) + v[:, None] * (c[:, 2] - c[:, 0])


def _report_points(points: FloatArray) -> tuple[FloatArray, float]:
    """The finite rows of ``points`` the report measures (a fixed subset beyond
    :data:`MAX_REPORT_POINTS`), and their bounding-box diagonal."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    pick = reduction_indices(len(points), MAX_REPORT_POINTS, seed=REPORT_SEED)
    if pick is not None:
        points = points[pick]
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
    return points, diagonal


def _distances(mesh: PolygonMesh, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(P,) distance of each point to the mesh's surface and (:data:`MESH_SAMPLES`,)
    distance of each surface sample to the nearest point; ``mesh`` has faces."""
    triangles, _ = triangles_of(mesh)
    _, gap = nearest_triangles(points, mesh.vertices, triangles)
    to_mesh = np.sqrt(np.maximum(gap, 0.0))
    samples = _surface_samples(mesh.vertices, triangles, MESH_SAMPLES)
    to_points, _ = cKDTree(points).query(samples)
    return to_mesh, np.asarray(to_points, dtype=np.float64)


def points_to_mesh_mean(mesh: PolygonMesh, points: FloatArray) -> float:
    """:attr:`FitReport.points_to_mesh_mean` alone: the mean distance from the points
    the report measures to ``mesh`` (infinite for a mesh without faces or no points)."""
    points, _ = _report_points(points)
    if mesh.n_faces == 0 or len(points) == 0:
        return float("inf")
    triangles, _ = triangles_of(mesh)
    return mean_distance(points, mesh.vertices, triangles)


def fit_score(mesh: PolygonMesh, points: FloatArray) -> float:
    """:attr:`FitReport.score` alone, without the topology and the intersection test.

    For choosing between candidate meshes of the same points: equal to
    ``fit_report(mesh, points).score``, infinite for a mesh without faces (or no points).
    """
    points, diagonal = _report_points(points)
    if mesh.n_faces == 0 or len(points) == 0:
        return float("inf")
    to_mesh, to_points = _distances(mesh, points)
    relative = diagonal if diagonal > 0 else 1.0
    return float(to_mesh.mean()) / relative + float(to_points.mean()) / relative


@dataclass(frozen=True)
class PointFacts:
    """What a generate knows of its points before any mesh is made, carried by every
    fit report of the request.

    Attributes
    ----------
    pieces : int
        The pieces of the surface the points sample
        (:func:`spacemesh.geometry.pieces.point_pieces`).
    outliers : float
        The share of the uploaded points set aside as outliers.
    noise : float
        The noise of the rest, a fraction of their diagonal
        (:func:`spacemesh.geometry.cleaning.assess_points`).
    """

    pieces: int
    outliers: float
    noise: float


@dataclass(frozen=True)
class SurfaceFacts:
    """What a generate decided about its surface (:mod:`spacemesh.geometry.surface`).

    Attributes
    ----------
    open : bool
        Whether the mesh was trimmed to its points.
    unsupported_area : float
        The share of the closed mesh's area that no point supports and no point lies in
        front of (:attr:`spacemesh.geometry.surface.SurfaceSupport.unsupported_area`).
    """

    open: bool
    unsupported_area: float


def fit_report(mesh: PolygonMesh, points: FloatArray, facts: PointFacts | None = None,
               tolerance: float | None = None, surface: SurfaceFacts | None = None
               ) -> FitReport:
    """The fit report of ``mesh`` against the finite rows of ``points``, made once with
    everything a response says.

    Parameters
    ----------
    mesh : PolygonMesh
        In the points' frame.
    points : (P, 3) float
    facts : PointFacts, optional
        A generate's facts of its points (``points_pieces``, ``points_outliers``,
        ``points_noise``).
    tolerance : float, optional
        A tolerance request's tolerance (``tolerance``; ``tolerance_met`` when
        ``points_to_mesh_mean_rel`` is within it).
    surface : SurfaceFacts, optional
        A generate's surface decision (``open_surface``, ``unsupported_area``).

    Returns
    -------
    FitReport
        Distances are NaN and coverage 0 for a mesh without faces.
    """
    points, diagonal = _report_points(points)
    relative = diagonal if diagonal > 0 else 1.0
    nan = float("nan")
    topology = surface_topology(mesh)
    components, _ = vertex_connected_faces(mesh)  # faces sharing a vertex are connected
    known = (None, None, None) if facts is None else (facts.pieces, facts.outliers,
                                                      facts.noise)
    decided = (None, None) if surface is None else (surface.open, surface.unsupported_area)
    if mesh.n_faces == 0 or len(points) == 0:
        return FitReport(nan, nan, nan, nan, nan, nan, nan, nan, 0.0, components,
                         0.0, diagonal, len(points), topology.pieces, topology.genus,
                         topology.boundary_loops, tolerance,
                         None if tolerance is None else False, points_pieces=known[0],
                         points_outliers=known[1], points_noise=known[2],
                         open_surface=decided[0], unsupported_area=decided[1],
                         face_planarity=face_planarity(mesh) / relative)
    to_mesh, to_points = _distances(mesh, points)
    to_mesh_mean, to_mesh_p95 = float(to_mesh.mean()), float(np.percentile(to_mesh, 95))
    to_points_mean = float(to_points.mean())
    to_points_p95 = float(np.percentile(to_points, 95))
    return FitReport(
        points_to_mesh_mean=to_mesh_mean, points_to_mesh_p95=to_mesh_p95,
        mesh_to_points_mean=to_points_mean, mesh_to_points_p95=to_points_p95,
        points_to_mesh_mean_rel=to_mesh_mean / relative,
        points_to_mesh_p95_rel=to_mesh_p95 / relative,
        mesh_to_points_mean_rel=to_points_mean / relative,
        mesh_to_points_p95_rel=to_points_p95 / relative,
        coverage=float(np.mean(to_mesh <= COVERAGE_FRACTION * relative)),
        components=components,
        self_intersections=self_intersection_fraction(mesh),
        diagonal=diagonal, n_points=len(points), pieces=topology.pieces,
        genus=topology.genus, boundary_loops=topology.boundary_loops,
        tolerance=tolerance,
        tolerance_met=None if tolerance is None else to_mesh_mean / relative <= tolerance,
        points_pieces=known[0], points_outliers=known[1], points_noise=known[2],
        open_surface=decided[0], unsupported_area=decided[1],
        face_planarity=face_planarity(mesh) / relative,
    )
