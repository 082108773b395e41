"""Whether a repair's new faces cross the mesh, the check that makes the repair sample a
region again (:data:`spacemesh.repair.api.TOPOLOGY_ATTEMPTS`), and the mending of the
new polygons that still cross once the samplings are spent (:func:`uncross_polygons`;
docs/REPAIR.md, "Limits").

The crossings a repair adds come mostly from its largest new faces: a loop the decode
could not close with its own faces is closed by one polygon (``polygon_loops``), and a
polygon of 7 to 46 corners over a curved region, read as triangles, passes through the
faces around it or through the triangles it shares corners with (5 of the 27 dev
repairs of experiments/repair_crossings.py before this mending). In order:

1. each such polygon is triangulated again: by the least-area triangulation of its
   corners (Liepa 2003, Sec. 3.1), or by a fan from a new vertex on the region's
   surface, whichever crosses nothing first;
2. two polygons that still cross, one at each end of a tube-like region, are replaced
   by the band between them (:func:`band_triangles`);
3. a new face that still crosses is merged with the new faces it shares a side with,
   and their border triangulated the same way.

Every step keeps a replacement only when its triangles cross nothing, so none adds a
crossing; what none of them mends stays as it was.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from spacemesh.geometry.intersections import crossing_faces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset, triangles_of
from spacemesh.primitives.closest import nearest_points
from spacemesh.repair.fill.flat import min_area_triangles
from spacemesh.repair.fill.loops import patch_loops
from spacemesh.repair.splice import Spliced
from spacemesh.typed import BoolArray, FloatArray, IntArray


def new_crossings(spliced: Spliced) -> int:
    """How many of a spliced mesh's new faces cross a face, new or kept
    (:func:`crossing_faces`)."""
    return len(crossing_faces(spliced.mesh, spliced.face_source < 0))


def uncross_polygons(spliced: Spliced, surface: PolygonMesh) -> tuple[Spliced, int]:
    """``spliced`` with its crossing new faces triangulated again so that their
    triangles cross nothing (the module's three steps).

    Each new polygon (4 corners or more) that crosses a face, or that a crossing new
    face shares a corner with, is tried first: the least-area triangulation of its
    corners, else a fan from a new vertex at the corners' centroid moved onto
    ``surface`` (the region's surface estimate), else from the centroid itself. Then
    the bridges and the merges. A face none of them uncrosses stays as it is.

    Kept faces and kept vertices stay as they are; the mesh stays a closed oriented
    manifold where it was one (a triangulation adds no edge the mesh has already, a
    fan's centre is a new vertex, and a band or a merge replaces whole discs).

    Returns
    -------
    spliced : Spliced
        New faces last, as before; fans' centres appended to the vertices, and new
        vertices inside merged faces dropped.
    count : int
        How many new faces were replaced (polygons triangulated alone, two a band, and
        the faces of each merge).
    """
    mesh, source = spliced.mesh, spliced.face_source
    crossing = crossing_faces(mesh, source < 0)
    if len(crossing) == 0:
        return spliced, 0
    suspects = [mesh.faces[f].copy() for f in
                _suspect_polygons(mesh, crossing, (source < 0) & (mesh.face_sizes >= 4))]
    mended = 0
    for corners in suspects:  # (n,) each; found again by position, as faces move
        one = np.zeros(mesh.n_faces, dtype=bool)
        one[_face_index(mesh, corners)] = True
        found = _uncrossed(mesh, source, one, corners, surface)
        if found is not None:
            (mesh, source), mended = found, mended + 1
    mesh, source, bridged = _bridge_crossing_polygons(mesh, source)
    mesh, source, merged = _merge_crossing_faces(mesh, source, surface)
    mended += 2 * bridged + merged
    if not mended:
        return spliced, 0
    mesh, vertex_map = _without_unused_vertices(mesh, spliced.vertex_map)
    added_vertices = mesh.n_vertices - spliced.mesh.n_vertices
    return Spliced(mesh, vertex_map, source, spliced.n_new_vertices + added_vertices,
                   int(np.sum(source < 0))), mended


def _without_unused_vertices(mesh: PolygonMesh, vertex_map: IntArray
                             ) -> tuple[PolygonMesh, IntArray]:
    """``mesh`` without the vertices no face uses any more (new vertices inside faces
    merged by :func:`_merge_crossing_faces`; a kept vertex is always on a kept face), and
    ``vertex_map`` (input vertex -> output vertex, -1: removed) renumbered to match."""
    used = np.zeros(mesh.n_vertices, dtype=bool)
    used[mesh.face_indices] = True
    if used.all():
        return mesh, vertex_map
    remap = np.where(used, np.cumsum(used) - 1, -1)  # (V,) new index, -1: dropped
    return (PolygonMesh(mesh.vertices[used], remap[mesh.face_indices], mesh.face_offsets),
            np.where(vertex_map >= 0, remap[np.maximum(vertex_map, 0)], -1))


def _uncrossed(mesh: PolygonMesh, source: IntArray, faces: BoolArray, corners: IntArray,
               surface: PolygonMesh) -> tuple[PolygonMesh, IntArray] | None:
    """``mesh`` and its faces' ``source`` with the ``faces`` ((F,) bool: one disc whose
    border is the loop ``corners``) replaced by the first of :func:`_triangulations`
    whose triangles cross nothing; None when each crosses."""
    for make in _triangulations(mesh, corners, surface):
        triangles, centre = make()
        found = None if triangles is None else _clear(mesh, source, faces, triangles, centre)
        if found is not None:
            return found
    return None


def _clear(mesh: PolygonMesh, source: IntArray, faces: BoolArray, triangles: IntArray,
           centre: FloatArray | None = None) -> tuple[PolygonMesh, IntArray] | None:
    """``mesh`` without the ``faces`` ((F,) bool), the ``triangles`` (T, 3) appended as
    new faces (and ``centre`` (3,), when given, as a new vertex), with its faces'
    ``source`` (-1 for the triangles); None when a triangle crosses a face."""
    kept = faces_subset(mesh, ~faces)
    if centre is not None:
        kept = PolygonMesh(np.concatenate([kept.vertices, centre[None]]), kept.face_indices,
                           kept.face_offsets)
    sizes = np.concatenate([kept.face_sizes, np.full(len(triangles), 3, dtype=np.int64)])
    trial = PolygonMesh(kept.vertices, np.concatenate([kept.face_indices,
                                                       triangles.reshape(-1)]),
                        np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64))
    added = np.arange(trial.n_faces) >= kept.n_faces
    if len(crossing_faces(trial, added)):
        return None
    return trial, np.concatenate([source[~faces], np.full(len(triangles), -1, np.int64)])


def _merge_crossing_faces(mesh: PolygonMesh, source: IntArray, surface: PolygonMesh
                          ) -> tuple[PolygonMesh, IntArray, int]:
    """Each new face that still crosses, merged with the new faces it shares a side with
    into one disc (when their border is one loop) and that disc triangulated again
    (:func:`_uncrossed`): a polygon folded over a new triangle that shares its corners is
    mended as a whole. Returns the mesh, the faces' sources and the number of faces
    merged.

    Tried without gain on the 24 test repairs (docs/REPAIR.md, "Limits"): merging every
    new face when the neighbours alone fail, and a band where the merged faces' border is
    two loops."""
    merged, tried = 0, set()
    while True:
        crossing = [f for f in crossing_faces(mesh, source < 0)
                    if tuple(mesh.faces[f]) not in tried]
        if not crossing:
            return mesh, source, merged
        face = crossing[0]
        tried.add(tuple(mesh.faces[face]))
        corners = set(mesh.faces[face].tolist())
        group = np.zeros(mesh.n_faces, dtype=bool)  # (F,) itself and its new neighbours
        group[[g for g in np.flatnonzero(source < 0)
               if len(corners & set(mesh.faces[g].tolist())) >= 2]] = True
        loops = patch_loops(mesh, group)
        if group.sum() < 2 or loops is None or len(loops) != 1:
            continue
        found = _uncrossed(mesh, source, group, loops[0], surface)
        if found is not None:
            (mesh, source), merged = found, merged + int(group.sum())


def _banded(mesh: PolygonMesh, source: IntArray, faces: BoolArray, first: IntArray,
            second: IntArray) -> tuple[PolygonMesh, IntArray] | None:
    """``mesh`` and its faces' ``source`` with the ``faces`` ((F,) bool: a region whose
    border is the loops ``first`` and ``second``, in its own direction) replaced by the
    band between the loops (:func:`band_triangles`); None where the band would repeat
    an edge of the mesh, where the loops share a corner, or where it crosses a face."""
    corners = np.concatenate([first, second])
    ends = mesh.halfedges[~faces[mesh.face_of_corner]]  # (S, 2) the sides of other faces
    in_first, in_second = (np.isin(ends, loop) for loop in (first, second))
    if ((in_first[:, 0] & in_second[:, 1]) | (in_second[:, 0] & in_first[:, 1])).any() \
            or len(np.unique(corners)) < len(corners):
        return None  # an edge between the loops exists already: not manifold
    return _clear(mesh, source, faces, band_triangles(mesh.vertices, first, second))


def _bridge_crossing_polygons(mesh: PolygonMesh, source: IntArray
                              ) -> tuple[PolygonMesh, IntArray, int]:
    """Each pair of new polygons that still cross, with no corner in common, replaced by
    a band of triangles between them (:func:`_banded`): two loops of a tube-like region
    each closed by its own polygon cut across the shape, where the band between them
    follows the region's surface. Closest pairs first; returns the mesh, the faces'
    sources and the number of pairs bridged."""
    bridged = 0
    while True:
        crossing = crossing_faces(mesh, source < 0)
        polygons = crossing[mesh.face_sizes[crossing] >= 4]
        if len(polygons) < 2:
            return mesh, source, bridged
        centres = np.array([mesh.vertices[mesh.faces[f]].mean(axis=0) for f in polygons])
        pairs = [(float(np.linalg.norm(centres[i] - centres[j])), polygons[i], polygons[j])
                 for i in range(len(polygons)) for j in range(i + 1, len(polygons))]
        for _, first, second in sorted(pairs):
            pair = np.zeros(mesh.n_faces, dtype=bool)
            pair[[first, second]] = True
            found = _banded(mesh, source, pair, mesh.faces[first], mesh.faces[second])
            if found is not None:
                (mesh, source), bridged = found, bridged + 1
                break
        else:
            return mesh, source, bridged


def band_triangles(vertices: FloatArray, first: IntArray, second: IntArray) -> IntArray:
    """The band of least area between two polygons of one oriented mesh that face away
    from each other (the two ends of a tube): ``(n + m, 3)`` triangles that use each
    polygon's sides in the polygon's own direction, so the band replaces both polygons
    and keeps the mesh oriented (a zip by dynamic programming from their closest pair of
    corners, the second polygon walked backwards)."""
    a = np.asarray(first, dtype=np.int64)
    b = np.asarray(second, dtype=np.int64)[::-1]  # walked backwards
    gap = np.linalg.norm(vertices[a][:, None] - vertices[b][None], axis=2)  # (n, m)
    i0, j0 = np.unravel_index(int(np.argmin(gap)), gap.shape)
    a, b = np.roll(a, -i0), np.roll(b, -j0)
    n, m = len(a), len(b)
    a_at = np.append(a, a[0])  # (n + 1,) the loop closed
    b_at = np.append(b, b[0])  # (m + 1,)

    def area(p: int, q: int, r: int) -> float:
        return 0.5 * float(np.linalg.norm(np.cross(vertices[q] - vertices[p],
                                                   vertices[r] - vertices[p])))

    cost = np.full((n + 1, m + 1), np.inf)
    came = np.zeros((n + 1, m + 1), dtype=np.int8)  # 1: from (i - 1, j), 2: (i, j - 1)
    cost[0, 0] = 0.0
    for i in range(n + 1):
        for j in range(m + 1):
            if i:  # a step along the first polygon
                step = cost[i - 1, j] + area(a_at[i - 1], a_at[i], b_at[j])
                if step < cost[i, j]:
                    cost[i, j], came[i, j] = step, 1
            if j:  # a step along the second
                step = cost[i, j - 1] + area(b_at[j], b_at[j - 1], a_at[i])
                if step < cost[i, j]:
                    cost[i, j], came[i, j] = step, 2
    triangles, i, j = [], n, m
    while i or j:
        if came[i, j] == 1:
            triangles.append((a_at[i - 1], a_at[i], b_at[j]))
            i -= 1
        else:
            triangles.append((b_at[j], b_at[j - 1], a_at[i]))
            j -= 1
    return np.asarray(triangles[::-1], dtype=np.int64).reshape(-1, 3)


def _suspect_polygons(mesh: PolygonMesh, crossing: IntArray, polygons: BoolArray) -> IntArray:
    """The new polygons among the ``crossing`` faces, then those that share a corner
    with a crossing face (a triangle that crosses a polygon's triangles it shares
    corners with is mended by the polygon), larger first within each."""
    touched = np.zeros(mesh.n_vertices, dtype=bool)
    touched[np.concatenate([mesh.faces[f] for f in crossing])] = True
    face = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    near = np.bincount(face, touched[mesh.face_indices], mesh.n_faces) > 0
    first = np.zeros(mesh.n_faces, dtype=bool)
    first[crossing] = True
    order = np.lexsort((-mesh.face_sizes, ~first))  # crossing first, then larger first
    return order[(polygons & (first | near))[order]]


def _face_index(mesh: PolygonMesh, corners: IntArray) -> int:
    """The index of the face of ``mesh`` whose corners are ``corners``, in order."""
    sizes = mesh.face_sizes
    for face in np.flatnonzero(sizes == len(corners)):
        start = mesh.face_offsets[face]
        if np.array_equal(mesh.face_indices[start:start + len(corners)], corners):
            return int(face)
    raise ValueError("no such face")  # a polygon is only replaced after it is found


def _triangulations(mesh: PolygonMesh, corners: IntArray, surface: PolygonMesh
                    ) -> list[Callable[[], tuple[IntArray | None, FloatArray | None]]]:
    """Ways to triangulate the polygon ``corners`` of ``mesh``, cheapest first; each
    gives ``(T, 3)`` vertex rows (None when it would repeat an edge of the mesh) and
    the position of the new vertex it adds (None: none)."""
    n = len(corners)
    centre_index = mesh.n_vertices  # the fan's new vertex

    def least_area() -> tuple[IntArray | None, FloatArray | None]:
        triangles = corners[min_area_triangles(mesh.vertices[corners])]  # (n - 2, 3)
        diagonals = {tuple(sorted(map(int, pair))) for tri in triangles
                     for pair in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0]))}
        diagonals -= {tuple(sorted(map(int, pair))) for pair in
                      zip(corners, np.roll(corners, -1), strict=True)}  # the sides
        ends = mesh.halfedges  # (S, 2); the edges among the corners only
        among = ends[np.isin(ends, corners).all(axis=1)]
        if diagonals & {tuple(sorted(map(int, pair))) for pair in among}:
            return None, None  # a diagonal the mesh has already: not manifold
        return triangles, None

    def fan(onto_surface: bool) -> tuple[IntArray | None, FloatArray | None]:
        centre = mesh.vertices[corners].mean(axis=0)  # (3,)
        if onto_surface and surface.n_faces:
            triangles, _ = triangles_of(surface)
            centre = nearest_points(centre[None], surface.vertices, triangles)[2][0]
        rows = np.stack([corners, np.roll(corners, -1), np.full(n, centre_index)], axis=1)
        return rows, centre

    return [least_area, lambda: fan(True), lambda: fan(False)]


__all__ = ["band_triangles", "new_crossings", "uncross_polygons"]
