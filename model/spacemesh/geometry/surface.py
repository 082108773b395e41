"""Open surfaces: a closed decode trimmed to where the points are (``surface=open``).

SpaceMesh decodes closed meshes. Points seen from one side (a scan from one direction)
come back as a closed shell whose far side no point supports. ``surface`` chooses:

* ``closed``: the closed decode as it is;
* ``open``: the decode trimmed to the points (:func:`open_surface`);
* ``auto`` (the default): open when at least :data:`AUTO_OPEN_SHARE` of the closed
  decode's area is unsupported *and unseen*: no point lies in front of it, along its
  outward normal (:func:`decide_open`). The far side of a one-sided scan faces away
  from every point; a face that no point supports but that points surround (a chord
  across a complete cloud, where a weak decode cut a corner) is not evidence of an open
  scan, and the mesh stays closed. The dev split's complete clouds (clean, 1% and 2%
  noise, 5% outliers) leave at most 13% unseen, but for one decode that closed a cavity
  over (34%); its one-sided scans leave 14% to 58%, all but one above 22%.

Support (:func:`face_support`): every point supports the face nearest to it, when it
lies within :data:`SUPPORT_SPACINGS` mean point spacings of it (a point far from the
mesh supports nothing). Unsupported patches of faces (edge-connected) whose area is at
most :data:`GAP_SHARE` of the mesh's are gaps between points, not unseen surface, and
count as supported. A complete cloud leaves almost nothing unsupported (noise and
outliers included: they add support, they do not remove it); a one-sided scan leaves
its far side.

Trimming (:func:`open_surface`) keeps the supported faces, so faces appear only where
points support them and the boundary follows the scan's rim. Where the kept faces
would pinch a vertex (two fans meeting at one corner), the faces of its smaller fans go
too, until no vertex is pinched; then pieces with a rim and less
than :data:`MIN_PIECE_SHARE` of the kept area are dropped. A subset of an oriented
edge-manifold mesh without pinched vertices is an oriented edge- and vertex-manifold
mesh with boundary: the decode's guarantee, with rims. Faces are only removed, never
moved or made, so trimming adds no crossing.

Orientation comes from the points, not from a signed volume (an open surface has
none): each open piece faces the side its points were seen from, the side away from
the part of its closed piece that no point supports. A piece whose area-weighted
normal points toward that unseen part is flipped.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.geometry.fitting import estimate_point_normals
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.geometry.orientation import oriented_normals
from spacemesh.geometry.report import SurfaceFacts
from spacemesh.geometry.stage import GeometryOptions, refine_geometry
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    component_labels,
    edge_keys,
    faces_subset,
    flip_faces,
    signed_volume,
    triangle_areas,
    triangle_normals,
    triangles_of,
)
from spacemesh.primitives.closest import candidate_triangles, mean_spacing
from spacemesh.topology import corner_fans, edge_connected_faces, face_adjacency
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: What ``surface`` may ask for.
SURFACE_MODES = ("auto", "closed", "open")
#: ``surface=auto`` opens the mesh when at least this share of the closed decode's area
#: is unsupported.
AUTO_OPEN_SHARE = 0.18
#: A point lies in front of a face when it is within this many mean point spacings of
#: the ray from the face's centre along its outward normal.
RAY_SPACINGS = 2.0
#: Unsupported faces whose rays :func:`_unseen` casts at most (the largest first).
MAX_RAYS = 256
#: A point supports its nearest face when within this many mean point spacings of it.
SUPPORT_SPACINGS = 3.0
#: Surface samples (16 per face) whose faces each point considers.
SUPPORT_CANDIDATES = 48
#: A face is supported only when at least this share of its area is within reach of a
#: point (a large face bridging the unseen side touches points along one edge only).
MIN_COVERED = 0.75
#: Unsupported patches of at most this share of the mesh's area count as supported.
GAP_SHARE = 0.02
#: Open pieces with less than this share of the kept area are dropped.
MIN_PIECE_SHARE = 0.02


@dataclass(frozen=True)
class SurfaceSupport:
    """Which faces of a closed mesh the points support.

    Attributes
    ----------
    supported : (F,) bool
        Faces some point supports, gaps between points included (module docstring).
    unsupported_area : float
        The share of the mesh's area that is not supported and faces away from every
        point (:func:`_unseen`), in [0, 1].
    """

    supported: BoolArray
    unsupported_area: float


def face_support(mesh: PolygonMesh, points: FloatArray,
                 normals: FloatArray | None = None) -> SurfaceSupport:
    """The faces of ``mesh`` that ``points`` support (see the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
        A closed mesh, in the points' frame.
    points : (P, 3) float
        Finite points, at least two.
    normals : (P, 3) float, optional
        The points' oriented normals (the upload's); estimated and oriented from the
        points without them (:func:`spacemesh.geometry.orientation.oriented_normals`).

    Returns
    -------
    SurfaceSupport
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if mesh.n_faces == 0 or len(points) < 2:
        return SurfaceSupport(np.zeros(mesh.n_faces, dtype=bool), 0.0)
    triangles, source = triangles_of(mesh)  # (T, 3), (T,)
    near, gap = candidate_triangles(points, mesh.vertices, triangles,
                                    k=SUPPORT_CANDIDATES)  # (P, k) each
    reach = (SUPPORT_SPACINGS * mean_spacing(points)) ** 2
    outward = -1.0 if signed_volume(mesh) < 0 else 1.0  # -1: the faces point inward
    normal = outward * triangle_normals(mesh.vertices[triangles])  # (T, 3)
    facing = (_facing(points, normal[near], gap <= reach) if normals is None
              else np.asarray(normals, np.float64))
    agree = np.einsum("pkd,pd->pk", normal[near], facing) > 0  # (P, k)
    # the nearest face on the side the point faces, else the nearest of all
    preferred = np.where(agree & (gap <= reach), gap, np.inf)
    best = np.where(np.isfinite(preferred).any(axis=1), np.argmin(preferred, axis=1),
                    np.argmin(gap, axis=1))  # (P,)
    rows = np.arange(len(points))
    supported = np.zeros(mesh.n_faces, dtype=bool)
    supported[source[near[rows, best][gap[rows, best] <= reach]]] = True
    triangle_area = triangle_areas(mesh.vertices, triangles)  # (T,)
    area = np.bincount(source, triangle_area, minlength=mesh.n_faces).astype(np.float64)
    covered = _covered(mesh, triangles, source, triangle_area, points, np.sqrt(reach))
    supported &= covered >= MIN_COVERED
    supported = _fill_gaps(mesh, supported, area)
    total = float(area.sum())
    unseen = _unseen(mesh, ~supported, area, outward, points,
                     np.sqrt(reach) / SUPPORT_SPACINGS)
    share = float(area[unseen].sum() / total) if total > 0 else 0.0
    return SurfaceSupport(supported, share)


def decide_open(mode: str, support: SurfaceSupport) -> bool:
    """Whether a request's mesh is trimmed to its points.

    Parameters
    ----------
    mode : {"auto", "closed", "open"}
    support : SurfaceSupport

    Returns
    -------
    bool
        ``open``: True; ``closed``: False; ``auto``: whether at least
        :data:`AUTO_OPEN_SHARE` of the area is unsupported and seen from no point.
    """
    if mode not in SURFACE_MODES:
        raise ValueError(f"surface must be one of {', '.join(SURFACE_MODES)}, not {mode!r}")
    if mode == "auto":
        return support.unsupported_area >= AUTO_OPEN_SHARE
    return mode == "open"


def open_surface(mesh: PolygonMesh, support: SurfaceSupport
                 ) -> tuple[PolygonMesh, dict[str, int | float]]:
    """``mesh`` trimmed to its supported faces (see the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
        A closed oriented manifold.
    support : SurfaceSupport
        From :func:`face_support` on ``mesh``.

    Returns
    -------
    mesh : PolygonMesh
        Oriented, edge- and vertex-manifold, with unused vertices removed; ``mesh``
        itself when every face is supported or none is.
    stats : dict
        ``faces_trimmed`` (all the faces removed), ``faces_unpinched`` (supported faces
        removed to unpinch vertices),
        ``pieces_dropped`` and ``pieces_flipped``.
    """
    stats: dict[str, int | float] = {"faces_trimmed": 0, "faces_unpinched": 0,
                                     "pieces_dropped": 0, "pieces_flipped": 0}
    kept = support.supported.copy()  # (F,)
    if kept.all() or not kept.any():
        return mesh, stats
    before = int(kept.sum())
    area = _face_areas(mesh)  # (F,)
    kept = _unpinched(mesh, kept, area)
    stats["faces_unpinched"] = before - int(kept.sum())
    kept, stats["pieces_dropped"] = _without_specks(mesh, kept, area)
    if not kept.any():
        return mesh, {key: 0 for key in stats}
    stats["faces_trimmed"] = int(mesh.n_faces - kept.sum())
    flip = _facing_away(mesh, kept)  # (F,) kept faces whose piece faces the unseen side
    stats["pieces_flipped"] = len(np.unique(_kept_labels(mesh, kept)[flip]))
    trimmed = faces_subset(flip_faces(mesh, flip), kept)
    result, _ = trimmed.remove_unreferenced_vertices()
    return result, stats


def drop_crossing_faces(mesh: PolygonMesh) -> tuple[PolygonMesh, int]:
    """An open surface without its faces that cross others (then, as in
    :func:`open_surface`, without pinched vertices and specks).

    Parameters
    ----------
    mesh : PolygonMesh
        An oriented edge- and vertex-manifold mesh with boundary.

    Returns
    -------
    mesh : PolygonMesh
        Without crossing faces and unused vertices; ``mesh`` itself when none crosses or
        every face does.
    dropped : int
        Faces removed.
    """
    crossing = self_intersecting_faces(mesh)  # (F,)
    if not crossing.any() or crossing.all():
        return mesh, 0
    area = _face_areas(mesh)  # (F,)
    kept = _unpinched(mesh, ~crossing, area)
    kept, _ = _without_specks(mesh, kept, area)
    if not kept.any():
        return mesh, 0
    result, _ = faces_subset(mesh, kept).remove_unreferenced_vertices()
    return result, int(mesh.n_faces - kept.sum())


def shape_surface(mesh: PolygonMesh, points: FloatArray, normals: FloatArray | None,
                  mode: str, options: GeometryOptions | None = None
                  ) -> tuple[PolygonMesh, SurfaceFacts, dict[str, Any]]:
    """A request's surface (``surface=mode``): the closed ``mesh`` as it is, or trimmed
    to ``points`` (:func:`open_surface`) when :func:`decide_open` says so, then fitted
    to them again (the geometry stage's vertex fit and guard, no flips: its rim is no
    longer held by the unseen side).

    Parameters
    ----------
    mesh : PolygonMesh
        A closed oriented manifold, in the points' frame.
    points : (P, 3) float
    normals : (P, 3) float, optional
        The upload's normals (:func:`face_support`, the fit).
    mode : {"auto", "closed", "open"}
    options : GeometryOptions, optional
        The model's geometry stage (its fit and guard).

    Returns
    -------
    mesh : PolygonMesh
    facts : SurfaceFacts
        The decision and its evidence, for the fit report.
    stats : dict
        :func:`open_surface`'s and ``surface_refit_kept`` (empty when the mesh stays
        closed).
    """
    support = face_support(mesh, points, normals)
    opened = decide_open(mode, support)
    facts = SurfaceFacts(opened, support.unsupported_area)
    if not opened:
        return mesh, facts, {}
    trimmed, stats = open_surface(mesh, support)
    if trimmed is mesh:
        return mesh, facts, dict(stats)
    refit_options = replace(options or GeometryOptions(), flips=False)
    refit = refine_geometry(trimmed, points, normals, refit_options)
    return refit.mesh, facts, {**stats, "surface_refit_kept": bool(refit.stats["kept"])}


def _facing(points: FloatArray, candidates: FloatArray, within: BoolArray) -> FloatArray:
    """(P, 3) the points' oriented normals: where every outward face within reach of a
    point lies on one side of its plane fit, that side; elsewhere (no face in reach, or
    both sides: two layers of the closed mesh close together) propagated from the
    others (:func:`spacemesh.geometry.orientation.oriented_normals`)."""
    plane = estimate_point_normals(points)  # (P, 3), signs arbitrary
    side = np.sign(np.einsum("pkd,pd->pk", candidates, plane)) * within  # (P, k)
    ahead, behind = (side > 0).any(axis=1), (side < 0).any(axis=1)
    votes = np.where(ahead & ~behind, 1.0, 0.0) - np.where(behind & ~ahead, 1.0, 0.0)
    return oriented_normals(points, plane, votes)


def _unseen(mesh: PolygonMesh, candidates: BoolArray, area: FloatArray, outward: float,
            points: FloatArray, spacing: float) -> BoolArray:
    """(F,) the ``candidates`` in front of which no point lies: no point within
    :data:`RAY_SPACINGS` spacings of the ray from the face's centre along its outward
    normal (``outward`` -1: the faces point inward), beyond one spacing from the centre
    (the :data:`MAX_RAYS` largest candidates by ``area`` are cast; smaller ones count as
    seen)."""
    unseen = np.zeros(mesh.n_faces, dtype=bool)
    chosen = np.flatnonzero(candidates)
    if len(chosen) == 0:
        return unseen
    chosen = chosen[np.argsort(-area[chosen], kind="stable")[:MAX_RAYS]]
    centre = mesh.face_centroids()[chosen]  # (R, 3)
    normal = outward * mesh.face_normals()[chosen]  # (R, 3)
    offset = points[None, :, :] - centre[:, None, :]  # (R, P, 3)
    along = np.einsum("rpd,rd->rp", offset, normal)  # (R, P)
    across = np.einsum("rpd,rpd->rp", offset, offset) - along ** 2
    blocked = ((along > spacing) & (across <= (RAY_SPACINGS * spacing) ** 2)).any(axis=1)
    unseen[chosen[~blocked]] = True
    return unseen


#: Barycentric coordinates of the samples :func:`_covered` takes on each triangle.
_COVER_SAMPLES = np.array([[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6],
                           [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


def _covered(mesh: PolygonMesh, triangles: IntArray, source: IntArray, areas: FloatArray,
             points: FloatArray, reach: float) -> FloatArray:
    """(F,) the share of each face's area within ``reach`` of some point (from
    :data:`_COVER_SAMPLES` on each of its triangles, weighted by their ``areas``)."""
    corners = mesh.vertices[triangles]  # (T, 3, 3)
    samples = np.einsum("sk,tkd->tsd", _COVER_SAMPLES, corners)  # (T, S, 3)
    distance, _ = cKDTree(points).query(samples.reshape(-1, 3))
    near = (distance <= reach).reshape(len(triangles), -1).mean(axis=1)  # (T,)
    covered = np.bincount(source, near * areas, minlength=mesh.n_faces)
    total = np.bincount(source, areas, minlength=mesh.n_faces)
    return np.divide(covered, total, out=np.ones(mesh.n_faces), where=total > 0)


def _fill_gaps(mesh: PolygonMesh, supported: BoolArray, area: FloatArray) -> BoolArray:
    """``supported`` with every unsupported edge-connected patch of at most
    :data:`GAP_SHARE` of the area added."""
    pairs = face_adjacency(mesh)  # (E, 2)
    both = ~supported[pairs[:, 0]] & ~supported[pairs[:, 1]]
    _, label = component_labels(mesh.n_faces, pairs[both])  # (F,)
    patch_area = np.bincount(label, area)
    small = patch_area[label] <= GAP_SHARE * float(area.sum())
    return supported | small


def _unpinched(mesh: PolygonMesh, kept: BoolArray, area: FloatArray) -> BoolArray:
    """``kept`` without the smaller fans of every pinched vertex: at a vertex where
    kept faces form several fans, the faces of all but the fan of largest area leave
    (it ends: faces only leave, and no face pinches nothing)."""
    kept = kept.copy()
    while True:
        sub = faces_subset(mesh, kept)
        fan = corner_fans(sub)  # (S',) fan of each corner of the kept faces
        if len(fan) == 0:
            return kept
        vertex = np.zeros(int(fan.max()) + 1, dtype=np.int64)
        vertex[fan] = sub.face_indices  # (N,) the vertex of each fan
        pinched = np.bincount(vertex, minlength=mesh.n_vertices) > 1  # (V,)
        if not pinched.any():
            return kept
        face = np.flatnonzero(kept)[sub.face_of_corner]  # (S',) the mesh face of each corner
        fan_area = np.bincount(fan, area[face])  # (N,)
        # the largest fan of each vertex (ties: the lower label) stays
        order = np.lexsort((np.arange(len(fan_area)), -fan_area, vertex))
        first = np.ones(len(order), dtype=bool)
        first[1:] = vertex[order][1:] != vertex[order][:-1]
        largest = np.zeros(len(fan_area), dtype=bool)
        largest[order[first]] = True
        leaving = pinched[vertex[fan]] & ~largest[fan]  # (S',) corners of smaller fans
        kept[face[leaving]] = False


def _kept_labels(mesh: PolygonMesh, kept: BoolArray) -> IntArray:
    """(F,) edge-connected piece of each kept face among the kept faces (-1 elsewhere)."""
    _, label = edge_connected_faces(faces_subset(mesh, kept))  # over kept faces, in order
    out = np.full(mesh.n_faces, -1, dtype=np.int64)
    out[kept] = label
    return out


def _face_areas(mesh: PolygonMesh) -> FloatArray:
    """(F,) the area of each face (of its triangles)."""
    triangles, source = triangles_of(mesh)
    areas = triangle_areas(mesh.vertices, triangles)  # (T,)
    return np.bincount(source, areas, minlength=mesh.n_faces).astype(np.float64)


def _without_specks(mesh: PolygonMesh, kept: BoolArray, area: FloatArray
                    ) -> tuple[BoolArray, int]:
    """``kept`` without its pieces that have a rim and less than
    :data:`MIN_PIECE_SHARE` of the kept ``area`` (how many were dropped). Pieces share
    no vertex (none is pinched), so dropping one pinches nothing."""
    label = _kept_labels(mesh, kept)  # (F,)
    n_pieces = int(label.max()) + 1
    piece_area = np.bincount(label[kept], area[kept], minlength=n_pieces)
    sub = faces_subset(mesh, kept)
    keys = edge_keys(sub.halfedges, sub.n_vertices)
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    rim_face = np.flatnonzero(kept)[sub.face_of_corner[counts[inverse] == 1]]
    has_rim = np.zeros(n_pieces, dtype=bool)
    has_rim[label[rim_face]] = True
    speck = has_rim & (piece_area < MIN_PIECE_SHARE * float(piece_area.sum()))
    if speck.all():
        return kept, 0
    return kept & ~speck[np.maximum(label, 0)], int(speck.sum())


def _facing_away(mesh: PolygonMesh, kept: BoolArray) -> BoolArray:
    """(F,) kept faces of the open pieces whose area-weighted normal points toward the
    trimmed part of their closed piece (the side no point saw)."""
    _, closed_piece = edge_connected_faces(mesh)  # (F,)
    label = _kept_labels(mesh, kept)
    triangles, source = triangles_of(mesh)
    corners = mesh.vertices[triangles]  # (T, 3, 3)
    weighted = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]) / 2
    area = np.linalg.norm(weighted, axis=1)  # (T,)
    centre = corners.mean(axis=1)  # (T, 3)
    flip = np.zeros(mesh.n_faces, dtype=bool)
    for piece in range(int(label.max()) + 1):
        mine = (label == piece)[source]  # (T,)
        unseen = (~kept[source]) & (closed_piece[source] == closed_piece[source[mine][0]])
        if not unseen.any():
            continue  # a whole closed piece: outward as decoded
        toward_seen = (_centroid(centre[mine], area[mine])
                       - _centroid(centre[unseen], area[unseen]))
        if float(weighted[mine].sum(axis=0) @ toward_seen) < 0:
            flip[label == piece] = True
    return flip


def _centroid(centres: FloatArray, weights: FloatArray) -> FloatArray:
    total = float(weights.sum())
    if total <= 0:
        return centres.mean(axis=0)
    return (centres * weights[:, None]).sum(axis=0) / total
