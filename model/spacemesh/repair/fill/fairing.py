"""Hole patches made to continue the surface around them (Liepa, "Filling holes in
meshes", SGP 2003).

A filled hole's new vertices are first placed where its filling put them (a fan, the
model's wedges), which on a curved surface is a flat or folded patch. Here the patch is

1. **refined** (:func:`~spacemesh.repair.fill.refine.refine_patch`): its large polygons
   are fanned from their centroid, every interior edge of its triangles longer than
   :data:`~spacemesh.repair.fill.refine.SPLIT_RATIO` times the target length (the mean
   length of the hole's boundary edges) is split at its midpoint, both triangles on it
   in two, then its interior edges are flipped towards Delaunay triangles, so that the
   patch has the density of the surface around it; quads, pentagons and the hole's
   boundary edges are never split;
2. **faired** (:func:`~spacemesh.repair.fill.laplace.fair_positions`): its vertices are
   moved to the solution of the discrete tri-Laplace equation ``L^3 x = 0`` or
   bi-Laplace equation ``L^2 x = 0`` (cotangent weights, re-read once from the first
   solution) with every other vertex fixed: the boundary ring and the rings of faces
   beyond it define the position, the slope and (tri-harmonic) the curvature the patch
   continues (a sparse solve); uniform weights or a membrane (``L x = 0``, within the
   hull of the ring), and around a sharp ring (flat clusters of faces meeting at a
   crease) a piecewise-planar continuation
   (:func:`~spacemesh.repair.fill.planar.planar_positions`), are the other candidates;
   the one kept (:func:`_continuation`) best predicts the ring itself when the ring is
   freed too, measured against the input's surface around it (a tri-harmonic or
   thin-plate surface that overshoots the box of the ring, as over a hole across sharp
   edges, is never kept; when all of them overshoot, the membrane is projected onto the
   least-area triangulation of the hole's loops,
   :func:`~spacemesh.repair.fill.flat.flat_positions`, the flat fill MeshFix-like tools
   make);
3. **guarded** (:func:`fair_patch`): the faired positions are kept only where they make no
   new self-intersection near the patch (the move is halved up to twice, else undone).

numpy and scipy only; no face outside the patch changes, and its topology is kept.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.cancel import checkpoint
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    faces_subset,
    faces_touching,
    triangle_normals,
    triangulate_faces,
    unit_rows,
    vertices_of,
)
from spacemesh.repair.fill.flat import MAX_FLAT_LOOP, flat_positions
from spacemesh.repair.fill.kinds import Fairing
from spacemesh.repair.fill.laplace import fair_positions
from spacemesh.repair.fill.planar import planar_positions, ring_planes
from spacemesh.repair.fill.refine import refine_patch
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: How far (a share of the largest side of the box of the fixed vertices around a
#: patch) a faired vertex may leave that box before a gentler fairing is used.
MAX_OVERSHOOT = 0.1
#: A gentler smooth fairing is used when its ring error is below this share of the
#: stiffer one's (:func:`_continuation`).
SMOOTH_MARGIN = 0.9
#: The planar continuation is used when its ring error is below this share of the
#: smooth fairing's (:func:`_continuation`).
PLANAR_MARGIN = 0.5
#: Rings of faces around a patch whose surface its freed ring is measured against.
SURFACE_RINGS = 3


def _contained(mesh: PolygonMesh, free: BoolArray, start: FloatArray,
               faired: FloatArray) -> bool:
    """Whether the ``faired`` free vertices stay within the box of the fixed vertices
    around them (two rings) widened by :data:`MAX_OVERSHOOT` of its largest side on
    every side (a thin plate over a hole across sharp edges overshoots; a membrane never
    leaves the hull of its ring)."""
    ring = vertices_of(mesh, faces_touching(mesh, free)) & ~free
    ring |= vertices_of(mesh, faces_touching(mesh, ring)) & ~free
    low, high = start[ring].min(axis=0), start[ring].max(axis=0)
    margin = MAX_OVERSHOOT * float((high - low).max())
    moved = faired[free]
    return bool(((moved >= low - margin) & (moved <= high + margin)).all())


def _surface_distance(mesh: PolygonMesh, faces: BoolArray, x: FloatArray,
                      steps: int = 4) -> FloatArray:
    """Distance of each point ``x`` to the plane of the triangle of the ``faces`` of
    ``mesh`` nearest to it (found among points on a barycentric grid of ``steps`` per
    side on each triangle), (N,)."""
    triangles, _ = triangulate_faces(faces_subset(mesh, faces))
    i, j = np.meshgrid(np.arange(steps + 1), np.arange(steps + 1), indexing="ij")
    keep = i + j <= steps
    a, b = i[keep] / steps, j[keep] / steps
    bary = np.stack([1 - a - b, a, b], axis=1)  # (G, 3)
    corners = mesh.vertices[triangles]  # (T, 3, 3)
    samples = np.einsum("gk,tkd->tgd", bary, corners).reshape(-1, 3)
    normal = unit_rows(triangle_normals(corners))  # (T, 3)
    nearest = cKDTree(samples).query(x)[1] // len(bary)
    return np.abs(np.einsum("ij,ij->i", x - corners[nearest, 0], normal[nearest]))


#: The smooth fairings tried, stiffest first, gentlest last: (order, weights) of
#: :func:`fair_positions`. The tri-harmonic ``L^3 x = 0`` also continues the curvature
#: of the surface around the hole (C2 where the thin plate is C1: Botsch & Kobbelt
#: 2004), which on the dev holes over smooth surfaces (a torus, spikes, a knight) came
#: closer to the intact surface, up to ten times; over sharp surroundings it
#: overshoots more, and the ring's box and ring score (:func:`_continuation`) then
#: keep a gentler one.
SMOOTH_FAIRINGS = ((3, "cotangent"), (2, "cotangent"), (2, "uniform"), (1, "uniform"))
#: Their names in reports.
FAIRING_NAMES = (Fairing.TRI_HARMONIC, Fairing.THIN_PLATE, Fairing.THIN_PLATE_UNIFORM,
                 Fairing.MEMBRANE)


def _continuation(mesh: PolygonMesh, free: BoolArray, patch: BoolArray, start: FloatArray,
                  max_flat_loop: int = MAX_FLAT_LOOP) -> tuple[FloatArray, float, Fairing]:
    """The continuation that best extends the surface around the hole, judged on the
    input mesh alone (leave the ring out).

    Each candidate is re-run with the hole's ring freed too, and scored by how far its
    freed ring lands from the input's faces around it (:data:`SURFACE_RINGS` rings; a
    distance to the surface, so a vertex sliding along it costs nothing). The
    candidates are the smooth fairings of :data:`SMOOTH_FAIRINGS` whose solution over
    the hole stays within the ring's box (:func:`_contained`), a later one taken only
    when its score is below :data:`SMOOTH_MARGIN` times the best so far, and, around a
    sharp ring, the piecewise-planar continuation (:func:`planar_positions`), taken when
    its score is below :data:`PLANAR_MARGIN` times the smooth one's. When neither the
    tri-harmonic surface nor a thin plate stays within the box (sharp surroundings),
    the membrane is replaced by the flat fill (:func:`flat_positions`, loops of at most
    ``max_flat_loop`` vertices: closer to the intact surface on every such dev hole).
    ``start`` when no candidate stays within the box.

    Returns the positions, the ring error of the candidate kept (of the membrane for
    the flat fill; infinite for ``start``) and its name (:data:`FAIRING_NAMES`,
    :attr:`Fairing.FLAT`, :attr:`Fairing.PLANAR` or :attr:`Fairing.NONE`)."""
    ring = vertices_of(mesh, faces_touching(mesh, free)) & ~free
    wider = free | ring
    around = wider
    for _ in range(SURFACE_RINGS):
        around = around | vertices_of(mesh, faces_touching(mesh, around))
    surface = faces_touching(mesh, around) & ~patch

    def score(guess: FloatArray) -> float:
        if not surface.any() or not ring.any():
            return math.inf  # nothing around the patch to continue
        return float(_surface_distance(mesh, surface, guess[ring]).mean())

    best, best_error, kind = start, math.inf, Fairing.NONE
    plate = False  # whether a tri-harmonic or thin-plate surface stays within the box
    for (order, weights), name in zip(SMOOTH_FAIRINGS, FAIRING_NAMES, strict=True):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        faired = fair_positions(mesh, free, order, weights)
        if not _contained(mesh, free, start, faired):
            continue
        plate |= order >= 2
        error = score(fair_positions(mesh, wider, order, weights))
        if error < SMOOTH_MARGIN * best_error:
            best, best_error, kind = faired, error, name
    if not plate:  # sharp surroundings: the flat least-area fill rather than a membrane
        flat = flat_positions(mesh, free, patch, best, max_flat_loop)
        if flat is not None:
            best, kind = flat, Fairing.FLAT
    checkpoint()
    found = ring_planes(mesh, free, patch)
    if found is None:
        return best, best_error, kind
    planes = found[:2]
    planar = planar_positions(mesh, free, patch, fair_positions(mesh, free, 1, "uniform"),
                              planes)
    guess = planar_positions(mesh, wider, patch | faces_touching(mesh, wider),
                             fair_positions(mesh, wider, 1, "uniform"), planes)
    assert planar is not None and guess is not None
    planar_error = score(guess)
    if planar_error < PLANAR_MARGIN * best_error:
        return planar, planar_error, Fairing.PLANAR
    return best, best_error, kind


def fair_patch(mesh: PolygonMesh, patch: BoolArray, free: BoolArray, target: float,
               *, refine: bool = True, report: dict | None = None,
               max_flat_loop: int = MAX_FLAT_LOOP) -> tuple[PolygonMesh, IntArray, int]:
    """Refine the patch to ``target`` edge length, fair its free vertices, and keep the
    faired positions only as far as they add no self-intersection near the patch.

    Parameters
    ----------
    mesh : PolygonMesh
    patch : (F,) bool
        The faces of the filled hole(s).
    free : (V,) bool
        The vertices that may move (the patch's own vertices; its ring stays fixed).
    target : float
        Edge length aimed at (for example :func:`boundary_edge_length` of its loops).
    refine : bool
        Split long edges first (:func:`refine_patch`).
    report : dict, optional
        Receives ``ring_error``: how far the ring, freed, lands from the surface around
        it under the fairing kept (:func:`_continuation`; the mean distance, mesh units),
        ``fairing``, the name of that fairing (a :class:`Fairing`), and ``weight``, the
        share of the move kept (1, or 0.5, 0.25 or 0 where the full move would add a
        self-intersection).
    max_flat_loop : int
        Longest loop the flat fill is made for (:func:`flat_positions`).

    Returns
    -------
    mesh : PolygonMesh
    face_source : (F',) int64
        The input face of each face (-1 for new ones); the input's vertices come first.
    added : int
        Vertices added by the refinement (all free).
    """
    source = np.arange(mesh.n_faces)
    n_before = mesh.n_vertices
    if refine:
        mesh, source = refine_patch(mesh, patch, target)
    added = mesh.n_vertices - n_before
    free = np.concatenate([free, np.ones(added, dtype=bool)])
    patch_after = (source < 0) | patch[np.maximum(source, 0)]
    if not free.any():
        return mesh, source, added
    start = np.asarray(mesh.vertices, dtype=np.float64)
    faired, error, kind = _continuation(mesh, free, patch_after, start, max_flat_loop)
    if report is not None:
        report.update(ring_error=error, fairing=kind)
    near = faces_touching(mesh, vertices_of(mesh, faces_touching(mesh, free)))
    local = faces_subset(mesh, near)

    def crossings(positions: FloatArray) -> int:
        return int(self_intersecting_faces(local.with_vertices(positions)).sum())

    before = crossings(mesh.vertices)
    for weight in (1.0, 0.5, 0.25):
        checkpoint()
        moved = start + weight * (faired - start)
        if crossings(moved) <= before:
            if report is not None:
                report["weight"] = weight
            return mesh.with_vertices(moved), source, added
    if report is not None:
        report["weight"] = 0.0
    return mesh, source, added
