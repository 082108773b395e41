"""The geometry stage: what happens to the decoded mesh before the user gets it.

After the networks and the decode have fixed a valid oriented manifold mesh, in the
normalised frame, :func:`refine_geometry`

1. splits its longest edges until it has the requested vertex count
   (:func:`split_longest_edges`; the network reads at most its token count), at most
   doubling the vertices at a time (:data:`SPLIT_STEP`), each step fitted as below
   before the next;
2. alternates the vertex fit (:func:`spacemesh.geometry.fitting.fit_vertices`: points
   -> mesh, mesh -> points, tangent-plane quadrics for sharp features, springs) with
   diagonal flips toward the points (:func:`spacemesh.decode.refinement.flip_diagonals` with
   the point fit only), each a manifold-keeping local operation;
3. guards self-intersections: vertices of faces that intersect after the fit but did
   not before go back toward where they were (halfway, then all the way); if the
   share of self-intersecting faces still grew, the whole fit is scaled back
   (:data:`GUARD_FRACTIONS` of each vertex's move) and, when no fraction keeps the
   share, the fit is made again without flips (moving vertices back cannot undo a
   flip), and when that does not keep the share either, the stage's result is dropped.

Edge splits and flips keep a closed oriented manifold closed, oriented and manifold,
and the fit moves positions only, so the decode's guarantee holds for the output.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.decode.refinement import flip_diagonals
from spacemesh.encode import connectivity_from_faces
from spacemesh.geometry.fitting import VertexFitOptions, fit_vertices, plane_fits
from spacemesh.geometry.intersections import (
    CrossingFaces,
    intersecting_triangles,
    self_intersecting_faces,
)
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangle_areas, triangles_of
from spacemesh.typed import FloatArray, IntArray

#: Most vertices a dense decode makes (:attr:`GeometryOptions.dense_factor`): the
#: connectivity network and the decode grow faster than linearly with the tokens.
MAX_DENSE_VERTICES = 1024
#: Rounds of the intersection guard's halfway backtracking.
GUARD_ROUNDS = 3
#: Rounds of the guard's full reverts after those.
MAX_REVERT_ROUNDS = 8
#: Fractions of every vertex's move the guard tries, largest first, when moving the
#: crossing faces' corners back did not keep the share of crossing faces.
GUARD_FRACTIONS = (0.5, 0.25, 0.125)
#: Most a step of edge splits multiplies the vertices by; a larger target is reached in
#: steps, each fitted before the next. Split 25 times over at once, a skull's 200-vertex
#: mesh crossed on 30% of its faces after the fit, and the guard undid the whole fit
#: (docs/GEOMETRY.md, "Splitting in steps").
SPLIT_STEP = 2
#: A triangle with at most this share of the squared diagonal as its area has collapsed
#: (three corners on a line: what moving a split vertex back can leave after a flip).
COLLAPSED_AREA = 1e-12


@dataclass(frozen=True)
class GeometryOptions:
    """What the geometry stage does (``manifest["geometry"]`` may override these).

    Attributes
    ----------
    fit : VertexFitOptions
        The vertex fit's weights.
    rounds : int
        Fit / flip rounds.
    flips : bool
        Flip diagonals toward the points between fits.
    fit_gain : float
        Relative gain a flip needs (:func:`spacemesh.decode.refinement.flip_diagonals`).
    guard : bool
        Never let the share of self-intersecting faces grow.
    dense_factor : float
        With ``start=points``, decode this many times the vertices asked for (at most
        :data:`MAX_DENSE_VERTICES`), fit it, and simplify it to the
        count asked for (:mod:`spacemesh.geometry.simplify`) before the fit; 1 (the
        default) decodes at the count asked for.
    dense_flips : bool
        Flip diagonals in the dense decode's fit before its collapses too (its
        :attr:`rounds` of fit are made either way; a decode with under
        :data:`spacemesh.geometry.finishing.DENSE_NO_FLIPS` times the count asked for is
        fitted with flips regardless). Off: synthetic tuning set ECD 4.24 -> 2.82e-2
        (docs/GEOMETRY.md, "The dense fit without flips").
    """

    fit: VertexFitOptions = field(default_factory=VertexFitOptions)
    rounds: int = 2
    flips: bool = True
    fit_gain: float = 0.2
    guard: bool = True
    dense_factor: float = 1.0
    dense_flips: bool = False

    def decode_vertices(self, wanted: int) -> int:
        """The vertices to decode for a mesh of ``wanted`` vertices: ``wanted`` times
        :attr:`dense_factor`, at most :data:`MAX_DENSE_VERTICES` (and never fewer than
        ``wanted``: so a request's cost grows with the count it asks for)."""
        if self.dense_factor <= 1:
            return wanted
        return max(wanted, min(round(self.dense_factor * wanted), MAX_DENSE_VERTICES))

    @classmethod
    def from_section(cls, section: dict[str, Any]) -> GeometryOptions:
        """From a manifest's ``geometry`` section (unknown keys are refused)."""
        fit_keys = set(VertexFitOptions.__dataclass_fields__)
        own = {k: v for k, v in section.items() if k in cls.__dataclass_fields__ and k != "fit"}
        fit = {k: v for k, v in section.get("fit", {}).items() if k in fit_keys}
        unknown = set(section) - set(cls.__dataclass_fields__) - {"why"}
        if unknown:
            raise ValueError(f"unknown geometry options {sorted(unknown)}")
        return cls(fit=VertexFitOptions(**fit), **own)


def geometry_section(options: GeometryOptions | None = None) -> dict[str, Any]:
    """A manifest's ``geometry`` section: every option, and why."""
    from dataclasses import asdict

    return {**asdict(options or GeometryOptions()),
            "why": "vertices fitted to the points (points -> mesh, mesh -> points, "
                   "tangent-plane quadrics for sharp features, springs), diagonals "
                   "flipped toward the points, self-intersections never increased"}


@dataclass
class GeometryResult:
    """The refined mesh and what the stage did.

    Attributes
    ----------
    mesh : PolygonMesh
    stats : dict
        ``n_split``, ``n_flipped``, ``energy_before`` / ``energy_after`` (of the first
        and last fit), ``intersections_before`` / ``intersections_after`` (shares of
        faces), ``n_guarded`` (vertices moved back), ``kept`` (False when the guard
        dropped the stage's result), ``split_steps`` (when the splits went in
        :data:`SPLIT_STEP` steps; counts are summed over them) and
        ``guard_without_flips`` (when the guard's fit without flips was kept).
    """

    mesh: PolygonMesh
    stats: dict[str, Any]


def _intersection_share(mesh: PolygonMesh, positions: FloatArray, triangles: IntArray,
                        source: IntArray | None) -> tuple[float, np.ndarray]:
    """The share of faces that intersect another face, and which of ``triangles`` are
    hit. A triangle mesh is measured on ``triangles``; a polygon mesh (``source``: the
    face of each triangle) face by face at ``positions``, triangulated anew."""
    if source is None:
        hit = intersecting_triangles(positions, triangles)
        return (float(hit.mean()) if len(hit) else 0.0), hit
    faces = self_intersecting_faces(mesh.with_vertices(positions))
    return (float(faces.mean()) if len(faces) else 0.0), faces[source]


def split_longest_edges(positions: FloatArray, triangles: IntArray, target: int
                        ) -> tuple[FloatArray, IntArray]:
    """Split edges at their midpoints, longest first, up to ``target`` vertices.

    Each split of edge ``a - b`` (triangles ``a b c`` and ``b a d``, ``c != d``) adds
    vertex ``m`` and four triangles ``a m c``, ``m b c``, ``b m d``, ``m a d``: a closed
    oriented manifold stays one. A pass splits edges that share no triangle; when no
    edge can split (a two-triangle pillow), the largest triangle splits at its centroid.

    Parameters
    ----------
    positions : (N, 3) float
    triangles : (T, 3) int
        Oriented triangles.
    target : int
        Vertex count to reach (nothing happens when ``N >= target``).

    Returns
    -------
    positions : (N', 3) float64
    triangles : (T', 3) int64
    """
    positions = np.asarray(positions, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    while len(positions) < target and len(tri):
        src, dst = tri.reshape(-1), np.roll(tri, -1, axis=1).reshape(-1)
        opp = np.roll(tri, -2, axis=1).reshape(-1)
        face = np.repeat(np.arange(len(tri)), 3)
        n = len(positions)
        key, twin_key = src * n + dst, dst * n + src
        order = np.argsort(key)
        at = np.minimum(np.searchsorted(key[order], twin_key), len(order) - 1)
        twin = order[at]
        half = np.flatnonzero((key[twin] == twin_key) & (src < dst))
        if len(half) == 0:
            break
        length = np.linalg.norm(positions[src[half]] - positions[dst[half]], axis=1)
        used = np.zeros(len(tri), dtype=bool)
        new_tri: list[tuple[int, int, int]] = []
        new_pos: list[FloatArray] = []
        drop: list[int] = []
        for h in half[np.argsort(-length, kind="stable")].tolist():
            if len(positions) + len(new_pos) >= target:
                break
            g = int(twin[h])
            f1, f2 = int(face[h]), int(face[g])
            a, b, c, d = int(src[h]), int(dst[h]), int(opp[h]), int(opp[g])
            if used[f1] or used[f2] or c == d:  # c == d: a two-triangle pillow
                continue
            used[f1] = used[f2] = True
            m = len(positions) + len(new_pos)
            new_pos.append((positions[a] + positions[b]) / 2)
            new_tri += [(a, m, c), (m, b, c), (b, m, d), (m, a, d)]
            drop += [f1, f2]
        if not new_pos:  # no edge can split (a pillow): split the largest triangle
            corners = positions[tri]
            f = int(np.argmax(triangle_areas(positions, tri)))
            a, b, c = tri[f].tolist()
            m = len(positions)
            new_pos.append(corners[f].mean(axis=0))
            new_tri += [(a, b, m), (b, c, m), (c, a, m)]
            drop.append(f)
        keep = np.ones(len(tri), dtype=bool)
        keep[drop] = False
        tri = np.concatenate([tri[keep], np.asarray(new_tri, dtype=np.int64)])
        positions = np.concatenate([positions, np.asarray(new_pos)])
    return positions, tri


def _flip_toward(positions: FloatArray, tri: IntArray, points: FloatArray, gain: float
                 ) -> tuple[IntArray, int]:
    n = len(positions)
    connectivity = connectivity_from_faces(list(tri), n)
    unused = (np.zeros((n, 1)), np.zeros((n, 1)))  # no score flips: the network is not read
    flipped, count = flip_diagonals(connectivity, unused, positions, by_score=False,
                                    points=points, fit_gain=gain)
    if count == 0:
        return tri, 0
    return np.stack(flipped.to_mesh(positions).faces).astype(np.int64), count


def _tracked_share(tracker: CrossingFaces, positions: FloatArray, source: IntArray | None
                   ) -> tuple[float, np.ndarray]:
    """:func:`_intersection_share` of the tracked mesh moved to ``positions``
    (:class:`~spacemesh.geometry.intersections.CrossingFaces`: only the triangles that
    touch a moved vertex are tested again; the same answer)."""
    faces = tracker.move(positions)  # (F,)
    return (float(faces.mean()) if len(faces) else 0.0), (faces if source is None
                                                          else faces[source])


def _backtrack(tracker: CrossingFaces, positions: FloatArray, unfitted: FloatArray,
               tri: IntArray, source: IntArray | None, hit: np.ndarray, limit: float,
               stats: dict[str, Any]) -> tuple[FloatArray, float]:
    """Move the corners of intersecting triangles back toward their unfitted positions
    (halfway for :data:`GUARD_ROUNDS` rounds, then all the way, round after round)
    until the share of intersecting triangles is at most ``limit``."""
    positions = positions.copy()
    guarded = np.zeros(len(positions), dtype=bool)
    share = limit
    for round_index in range(GUARD_ROUNDS + MAX_REVERT_ROUNDS):
        checkpoint()
        corners = np.unique(tri[hit].reshape(-1))
        guarded[corners] = True
        weight = 0.5 if round_index < GUARD_ROUNDS else 1.0
        positions[corners] += weight * (unfitted[corners] - positions[corners])
        share, hit = _tracked_share(tracker, positions, source)
        if share <= limit or not hit.any():
            break
    stats["n_guarded"] = int(guarded.sum())
    return positions, share


def _scaled_back(tracker: CrossingFaces, positions: FloatArray, unfitted: FloatArray,
                 source: IntArray | None, limit: float, stats: dict[str, Any]
                 ) -> tuple[FloatArray, float] | None:
    """The largest of :data:`GUARD_FRACTIONS` of every vertex's move from ``unfitted``
    whose share of intersecting triangles is at most ``limit``, with that share
    (``stats["guard_fraction"]`` says which); None when no fraction keeps it."""
    for fraction in GUARD_FRACTIONS:
        checkpoint()
        trial = unfitted + fraction * (positions - unfitted)
        share, _ = _tracked_share(tracker, trial, source)
        if share <= limit:
            stats["guard_fraction"] = fraction
            return trial, share
    return None


def _guarded(mesh: PolygonMesh, positions: FloatArray, unfitted: FloatArray, tri: IntArray,
             source: IntArray | None, limit: float, guard: bool, stats: dict[str, Any]
             ) -> tuple[FloatArray, float]:
    """The fitted ``positions`` and their share of crossing faces, with the guard when
    ``guard``: the crossing faces' corners moved back (:func:`_backtrack`), then every
    move scaled back (:func:`_scaled_back`), while the share is above ``limit``."""
    fitted_mesh = (mesh.with_vertices(positions) if source is not None else
                   PolygonMesh.from_faces(positions, tri))
    tracker = CrossingFaces(fitted_mesh)  # the guard's rounds test only what they move
    share, hit = _tracked_share(tracker, positions, source)
    if guard and share > limit:
        positions, share = _backtrack(tracker, positions, unfitted, tri, source, hit, limit,
                                      stats)
    if guard and share > limit:
        scaled = _scaled_back(tracker, positions, unfitted, source, limit, stats)
        if scaled is not None:
            positions, share = scaled
    return positions, share


def _collapsed_count(positions: FloatArray, tri: IntArray) -> int:
    """Triangles whose area is at most :data:`COLLAPSED_AREA` of the squared diagonal."""
    diagonal = float(np.linalg.norm(np.ptp(positions, axis=0))) if len(positions) else 0.0
    return int((triangle_areas(positions, tri) <= COLLAPSED_AREA * diagonal**2).sum())


def _chained(first: dict[str, Any], last: dict[str, Any]) -> dict[str, Any]:
    """The statistics of two geometry stages run one after the other: counts summed,
    the first's state before and the last's after, ``split_steps`` counted."""
    chained = {**last, **{key: first.get(key, 0) + last.get(key, 0)
                          for key in ("n_split", "n_flipped", "n_guarded")}}
    for key in ("energy_before", "intersections_before"):
        if key in first:
            chained[key] = first[key]
    chained["split_steps"] = first.get("split_steps", 1) + last.get("split_steps", 1)
    return chained


def refine_geometry(
    mesh: PolygonMesh,
    points: FloatArray,
    normals: FloatArray | None = None,
    options: GeometryOptions | None = None,
    *,
    target_vertices: int | None = None,
    fixed: np.ndarray | None = None,
) -> GeometryResult:
    """Fit a decoded mesh to its points (see the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
        A valid decode, in the points' frame; triangle meshes get every operation,
        polygon meshes only the vertex fit (on a triangulation).
    points : (P, 3) float
        Conditioning points (non-finite rows are left out).
    normals : (P, 3) float, optional
        Their normals (estimated when None).
    options : GeometryOptions, optional
    target_vertices : int, optional
        Split edges up to this many vertices first.
    fixed : (N,) bool, optional
        Vertices that must not move (a repair's kept vertices). With it, no edge is
        split or flipped, so every face between fixed vertices stays as it is.

    Returns
    -------
    GeometryResult
    """
    options = options or GeometryOptions()
    if (fixed is None and mesh.is_triangle_mesh() and target_vertices is not None
            and target_vertices > SPLIT_STEP * mesh.n_vertices > 0):
        step = refine_geometry(mesh, points, normals, options,
                               target_vertices=SPLIT_STEP * mesh.n_vertices)
        if step.mesh.n_vertices <= mesh.n_vertices:  # nothing left to split
            return step
        rest = refine_geometry(step.mesh, points, normals, options,
                               target_vertices=target_vertices)
        return GeometryResult(rest.mesh, _chained(step.stats, rest.stats))
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    finite = np.isfinite(points).all(axis=1)
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)[finite]
        normals = normals if np.isfinite(normals).all() else None
    points = points[finite]
    stats: dict[str, Any] = {"n_split": 0, "n_flipped": 0, "n_guarded": 0, "kept": True}
    if mesh.n_faces == 0 or len(points) < 4 or not np.isfinite(mesh.vertices).all():
        stats["kept"] = False
        return GeometryResult(mesh, stats)
    triangle_mesh = mesh.is_triangle_mesh()
    edits = fixed is None  # splits and flips only when every vertex may move
    start_positions = mesh.vertices.astype(np.float64)
    if triangle_mesh:
        tri, source = mesh.face_indices.reshape(-1, 3).astype(np.int64), None
    else:  # polygons: the fit only, on a triangulation
        tri, source = triangles_of(mesh)
    positions: FloatArray = start_positions
    if (edits and triangle_mesh and target_vertices is not None
            and target_vertices > len(positions)):
        positions, tri = split_longest_edges(positions, tri, target_vertices)
        stats["n_split"] = len(positions) - len(start_positions)
    before_share, _ = _intersection_share(mesh, positions, tri, source)
    unfitted, unflipped = positions.copy(), tri.copy()
    fitted, noise = plane_fits(points)  # once for every round
    normals = fitted if normals is None else normals

    def later_rounds(start: FloatArray, faces: IntArray, flips: bool
                     ) -> tuple[FloatArray, IntArray, list[float], int]:
        """The rounds of fit after the first, from ``start`` on ``faces``, with diagonal
        flips toward the points before each when ``flips``; the positions, the faces,
        the rounds' energies and how many diagonals flipped."""
        energies: list[float] = []
        flipped = 0
        for _ in range(1, max(options.rounds, 1)):
            checkpoint()
            if flips:
                faces, count = _flip_toward(start, faces, points, options.fit_gain)
                flipped += count
            start, round_energies = fit_vertices(start, faces, points, normals, options.fit,
                                                 fixed, noise)
            energies += round_energies
        return start, faces, energies, flipped

    checkpoint()  # abandoned work stops here (spacemesh.cancel)
    # the first round flips nothing: the guard's fit without flips starts from it too
    first, first_energies = fit_vertices(positions, tri, points, normals, options.fit, fixed,
                                         noise)
    positions, tri, later, stats["n_flipped"] = later_rounds(
        first, tri, edits and triangle_mesh and options.flips)
    energies = first_energies + later
    stats.update(energy_before=energies[0] if energies else None,
                 energy_after=energies[-1] if energies else None,
                 intersections_before=before_share)
    positions, share = _guarded(mesh, positions, unfitted, tri, source, before_share,
                                options.guard, stats)
    # moving a split vertex back onto the edge that a flip then made leaves that flip's
    # triangle without area: the guard refuses that as it refuses a crossing
    collapsed = (options.guard and stats["n_flipped"] > 0
                 and _collapsed_count(positions, tri) > _collapsed_count(unfitted, unflipped))
    if options.guard and (share > before_share or collapsed) and stats["n_flipped"]:
        # moving vertices back cannot undo a flip: the rounds after the first again on
        # the unflipped mesh, without flips, and the guard
        again_stats: dict[str, Any] = {"n_guarded": 0}
        again, _, again_later, _ = later_rounds(first, unflipped, False)
        again, again_share = _guarded(mesh, again, unfitted, unflipped, source, before_share,
                                      True, again_stats)
        if again_share <= before_share:
            again_energies = first_energies + again_later
            stats.update(again_stats, n_flipped=0, guard_without_flips=True,
                         energy_after=again_energies[-1] if again_energies else None)
            positions, tri, share, collapsed = again, unflipped, again_share, False
    if options.guard and (share > before_share or collapsed):
        stats["kept"] = False
        share = before_share
        positions, tri = unfitted, unflipped
    stats["intersections_after"] = share
    if not triangle_mesh:
        return GeometryResult(mesh.with_vertices(positions), stats)
    out = PolygonMesh.from_faces(positions, tri)
    return GeometryResult(out, stats)
