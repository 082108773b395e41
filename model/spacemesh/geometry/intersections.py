"""Self-intersecting faces with numpy and scipy only (the serving install has no
pymeshlab).

Candidate pairs are triangles whose bounding spheres overlap (one KD-tree query);
:func:`triangle_pairs_intersect`, the vectorised form of
:func:`spacemesh.data.validate.triangles_intersect` (a test holds the two together),
drops the pairs where one triangle lies strictly on one side of the other's plane and
confirms the rest exactly. Pairs that share corners have exact rules of their own, so
that the shared edge or corner does not count: two triangles on one corner cross when a
ray from it lies in both (:func:`_one_corner_cross`), two on one edge only when folded
onto each other (a fin), and two on the same three corners always; triangles of the same
polygon face are never compared (:func:`pairs_cross` holds every rule; the fit report,
the evaluation's metric and the guard all read this module).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    bounding_spheres,
    cross_rows,
    faces_subset,
    triangle_normals,
    triangles_of,
    unique_edges,
    unit_rows,
)
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Pairs whose corners all lie within this fraction of their size of the other's plane
#: are coplanar (rounding of float32 files is about 1e-7 of the size).
COPLANAR_TOLERANCE = 1e-5
#: Two triangles on one edge cross only when folded onto each other: their normals' dot
#: product is below minus this (cos 0.1 degree: a fin whose gap at its far corner is
#: under 0.2% of its size, which slicers and PyMeshLab's check read as crossing; 2.6
#: degrees cost 8% ECD on the tuning set, docs/GEOMETRY.md "Fins").
FOLDED_COSINE = 0.9999985
#: Near contacts (``floor`` of :func:`pairs_cross`) of two triangles on one corner are
#: looked for away from it: on copies shrunk by this fraction of their size towards their
#: centres (which keeps the seeds' check as it was tuned: docs/GEOMETRY.md, "One corner").
NEAR_SHRINK = 1e-3
#: :meth:`CrossingFaces.move` tests every pair again (one candidate search) instead of the
#: pairs of the moved triangles when more than this share of the triangles moved.
FULL_RETEST_SHARE = 0.5
#: Two triangles closer than this fraction of their own extent touch (count as
#: crossing). Each pair's verdict depends on that pair alone, so two triangles that stay
#: as they are keep their verdict whatever else the mesh gains or loses (a repair's kept
#: faces, a collapse's neighbours).
TOUCHING_SHARE = 1e-9


def _spread(corners: FloatArray) -> FloatArray:
    """``(M,)`` the largest extent along an axis of each row of ``corners`` ``(M, K, 3)``:
    ``np.ptp(corners, axis=1).max(axis=1)``, corner by corner (a reduction over the
    middle axis is several times slower; the same numbers)."""
    high = corners[:, 0].copy()  # (M, 3)
    low = high.copy()
    for k in range(1, corners.shape[1]):
        np.maximum(high, corners[:, k], out=high)
        np.minimum(low, corners[:, k], out=low)
    return (high - low).max(axis=1)


def _unit_normals(t: FloatArray) -> tuple[FloatArray, BoolArray]:
    normal = triangle_normals(t)  # (M, 3)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    return normal / np.where(length > 0, length, 1.0), length[:, 0] > 0


def _segments_hit(p0: FloatArray, p1: FloatArray, t: FloatArray, normal: FloatArray,
                  eps: FloatArray) -> BoolArray:
    """``(M,)`` whether segments ``p0 - p1`` cross triangles ``t`` (M, 3, 3) away from
    their plane (a segment in the plane is left to the coplanar test; ``eps`` ``(M,)``
    the touching distance of each)."""
    s0 = np.einsum("md,md->m", p0 - t[:, 0], normal)
    s1 = np.einsum("md,md->m", p1 - t[:, 0], normal)
    apart = ((s0 > eps) & (s1 > eps)) | ((s0 < -eps) & (s1 < -eps))
    flat = np.abs(s0 - s1) <= eps
    step = np.where(flat, 1.0, s0 - s1)
    x = p0 + (s0 / step)[:, None] * (p1 - p0)  # (M, 3) where the segment meets the plane
    inside = np.ones(len(p0), dtype=bool)
    for k in range(3):
        u, w = t[:, k], t[:, (k + 1) % 3]
        inward = unit_rows(cross_rows(normal, w - u))
        inside &= np.einsum("md,md->m", x - u, inward) >= -eps
    return ~apart & ~flat & inside


def _coplanar_overlap(ta: FloatArray, tb: FloatArray, normal: FloatArray, eps: FloatArray
                      ) -> BoolArray:
    """``(M,)`` separating-axis test of coplanar triangle pairs in their plane: they
    overlap when no axis separates them by more than ``-eps`` (``(M,)``: overlaps within
    rounding do not count)."""
    axis = np.argmax(np.abs(normal), axis=1)  # (M,)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[axis]  # (M, 2)
    rows = np.arange(len(ta))[:, None, None]
    a2 = ta[rows, np.arange(3)[None, :, None], keep[:, None, :]]  # (M, 3, 2)
    b2 = tb[rows, np.arange(3)[None, :, None], keep[:, None, :]]
    overlap = np.ones(len(ta), dtype=bool)
    for poly in (a2, b2):
        for k in range(3):
            edge = poly[:, (k + 1) % 3] - poly[:, k]
            n = np.stack([-edge[:, 1], edge[:, 0]], axis=1)
            length = np.linalg.norm(n, axis=1, keepdims=True)
            n = n / np.where(length > 0, length, 1.0)
            pa, pb = np.einsum("mkd,md->mk", a2, n), np.einsum("mkd,md->mk", b2, n)
            apart = (pa.max(axis=1) < pb.min(axis=1) + eps) | (
                pb.max(axis=1) < pa.min(axis=1) + eps)
            overlap &= ~(apart & (length[:, 0] > 0))
    return overlap


def triangle_pairs_intersect(ta: FloatArray, tb: FloatArray,
                             eps: float | FloatArray = 1e-9) -> BoolArray:
    """:func:`spacemesh.data.validate.triangles_intersect` for many pairs at once.

    Parameters
    ----------
    ta, tb : (M, 3, 3) float
        Corner positions of the pairs (pairs that share no corner: shared corners always
        touch).
    eps : float or (M,) float
        Distance below which touching counts as intersecting (one for all pairs, or one
        per pair).

    Returns
    -------
    (M,) bool
    """
    ta, tb = np.asarray(ta, dtype=np.float64), np.asarray(tb, dtype=np.float64)
    eps = np.broadcast_to(np.asarray(eps, dtype=np.float64), (len(ta),))  # (M,)
    na, good_a = _unit_normals(ta)
    nb, good_b = _unit_normals(tb)
    da = np.einsum("mkd,md->mk", tb - ta[:, None, 0], na)  # b's corners from a's plane
    db = np.einsum("mkd,md->mk", ta - tb[:, None, 0], nb)
    column = eps[:, None]  # (M, 1)
    apart = (np.all(da > column, axis=1) | np.all(da < -column, axis=1)
             | np.all(db > column, axis=1) | np.all(db < -column, axis=1))
    # within rounding of one plane (float32 files): the in-plane test decides, since a
    # crossing point of nearly parallel planes is ill-conditioned
    size = np.maximum(_spread(ta), _spread(tb))
    flat = np.maximum(eps, COPLANAR_TOLERANCE * size)[:, None]  # (M, 1)
    coplanar = np.all(np.abs(da) <= flat, axis=1) & np.all(np.abs(db) <= flat, axis=1)
    # the exact tests only for the pairs still open: one triangle is not strictly on one
    # side of the other's plane, neither is degenerate (every test is row by row)
    out = np.zeros(len(ta), dtype=bool)
    live = ~apart & good_a & good_b
    plane = np.flatnonzero(live & coplanar)
    if len(plane):
        out[plane] = _coplanar_overlap(ta[plane], tb[plane], na[plane], flat[plane, 0])
    cut = np.flatnonzero(live & ~coplanar)
    if len(cut):
        out[cut] = _edges_cross(ta[cut], tb[cut], na[cut], nb[cut], eps[cut])
    return out


def _edges_cross(ta: FloatArray, tb: FloatArray, na: FloatArray, nb: FloatArray,
                 eps: FloatArray) -> BoolArray:
    """``(M,)`` whether an edge of one triangle of each pair crosses the other away from
    its plane (:func:`_segments_hit`, the six edges of a pair tested in one call; ``eps``
    ``(M,)``)."""
    m = len(ta)
    start = np.concatenate([ta, tb], axis=1).transpose(1, 0, 2).reshape(-1, 3)  # (6M, 3)
    end = np.concatenate([ta[:, [1, 2, 0]], tb[:, [1, 2, 0]]], axis=1)
    end = end.transpose(1, 0, 2).reshape(-1, 3)
    other = np.concatenate([np.broadcast_to(tb, (3, m, 3, 3)),
                            np.broadcast_to(ta, (3, m, 3, 3))]).reshape(-1, 3, 3)
    normal = np.concatenate([np.broadcast_to(nb, (3, m, 3)),
                             np.broadcast_to(na, (3, m, 3))]).reshape(-1, 3)
    hit = _segments_hit(start, end, other, normal, np.tile(eps, 6))  # (6M,)
    return np.any(hit.reshape(6, m), axis=0)


def intersecting_triangles(vertices: FloatArray, triangles: IntArray,
                           source_face: IntArray | None = None, *,
                           whole_extent: bool = False) -> BoolArray:
    """Which triangles intersect another triangle (not of the same face).

    Parameters
    ----------
    vertices : (V, 3) float
    triangles : (T, 3) int
    source_face : (T,) int, optional
        The polygon face of each triangle (triangles of one face are not compared).
    whole_extent : bool
        Near contacts count too (:func:`crossing_pairs`).

    Returns
    -------
    (T,) bool
    """
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    pairs = crossing_pairs(vertices, triangles, source_face, whole_extent=whole_extent)
    hit = np.zeros(len(triangles), dtype=bool)
    hit[pairs.reshape(-1)] = True
    return hit


def touching_eps(vertices: FloatArray, triangles: IntArray) -> float:
    """The largest distance below which two of the triangles can touch
    (:data:`TOUCHING_SHARE` of the extent of ``vertices`` used by ``triangles``): the
    margin of the candidate search, never smaller than a pair's own
    (:func:`pairs_cross`)."""
    extent = float(np.ptp(vertices[triangles.reshape(-1)], axis=0).max())
    return TOUCHING_SHARE * (extent or 1.0)


def crossing_pairs(vertices: FloatArray, triangles: IntArray,
                   source_face: IntArray | None = None, among: IntArray | None = None,
                   *, whole_extent: bool = False) -> IntArray:
    """The pairs of triangles that intersect (:func:`pairs_cross`), each once.

    Parameters
    ----------
    vertices : (V, 3) float
    triangles : (T, 3) int
    source_face : (T,) int, optional
        The polygon face of each triangle (triangles of one face are not compared).
    among : (K,) int, optional
        Only the pairs with at least one of these triangles (default: every pair).
    whole_extent : bool
        Two triangles touch within :data:`TOUCHING_SHARE` of the extent of every triangle
        (:func:`touching_eps`) instead of the pair's own: near contacts count too
        (:func:`near_contact_faces`).

    Returns
    -------
    (P, 2) int
        ``[i, j]`` with ``i < j``, in no promised order.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    none = np.zeros((0, 2), dtype=np.int64)
    if len(triangles) < 2 or (among is not None and len(among) == 0):
        return none
    corners = vertices[triangles]  # (T, 3, 3)
    centre, radius = bounding_spheres(corners)  # (T, 3), (T,)
    eps = touching_eps(vertices, triangles)
    tree = cKDTree(centre)
    pairs = _larger_first_pairs(tree, centre, radius, eps, among)
    if len(pairs) == 0:
        return none
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(centre[i] - centre[j], axis=1) <= radius[i] + radius[j] + eps
    if source_face is not None:
        near &= source_face[i] != source_face[j]
    i, j = i[near], j[near]
    crossing = pairs_cross(vertices, triangles, i, j, floor=eps if whole_extent else 0.0)
    return np.stack([i[crossing], j[crossing]], axis=1)


def _flat_hits(found: Any) -> tuple[IntArray, IntArray]:
    """The hits of a ball query (one list per query point) as ``(queries, hits)``, one
    row per hit."""
    count = np.fromiter((len(f) for f in found), dtype=np.int64, count=len(found))
    hits = np.fromiter((k for f in found for k in f), dtype=np.int64, count=int(count.sum()))
    return np.repeat(np.arange(len(found)), count), hits


def _larger_first_pairs(tree: cKDTree, centre: FloatArray, radius: FloatArray, eps: float,
                        among: IntArray | None = None) -> IntArray:
    """The pairs of bounding spheres (``centre`` ``(T, 3)`` of ``tree``, ``radius``
    ``(T,)``) that may come within ``eps`` of each other, each found from its larger
    sphere within twice its radius (a search radius that follows each triangle: one
    radius for all, twice the largest, made a mesh with a few long triangles compare
    every triangle with hundreds of others); with ``among`` ``(K,)``, only the pairs with
    one of those. ``(P, 2)``, ``i < j`` in each row, each pair once."""
    # (twice eps: the tree's rounding of a distance can never drop a pair the caller's
    # test of ``ri + rj + eps`` keeps)
    reach = 2 * radius + 2 * eps  # (T,)
    if among is None:
        i, j = _flat_hits(tree.query_ball_point(centre, reach, return_sorted=False))
    else:  # from each of ``among``, and into them from every triangle
        among = np.asarray(among, dtype=np.int64)
        first, near = _flat_hits(tree.query_ball_point(centre[among], reach[among],
                                                       return_sorted=False))
        into, local = _flat_hits(cKDTree(centre[among]).query_ball_point(
            centre, reach, return_sorted=False))
        i = np.concatenate([among[first], into])
        j = np.concatenate([near, among[local]])
    # from the larger of the two (equal radii: from the higher index), so once each
    keep = (radius[j] < radius[i]) | ((radius[j] == radius[i]) & (j < i))
    pairs = np.stack([np.minimum(i[keep], j[keep]), np.maximum(i[keep], j[keep])], axis=1)
    return pairs if among is None else unique_edges(pairs, len(centre))


class CrossingFaces:
    """Which faces of a mesh cross another, kept up to date as its vertices move: only
    the pairs with a triangle that touches a moved vertex are tested again, so each
    answer is :func:`self_intersecting_faces` of the moved mesh at a fraction of its
    cost (each pair's verdict depends on its own corners only; a polygon triangulated
    otherwise at the new positions tests everything again).

    Parameters
    ----------
    mesh : PolygonMesh
        The connectivity, and the first positions.
    """

    def __init__(self, mesh: PolygonMesh) -> None:
        self.mesh = mesh
        self.n_faces = mesh.n_faces
        self.triangles, self.source = triangles_of(mesh)  # (T, 3), (T,)
        self.vertices = np.asarray(mesh.vertices, dtype=np.float64).copy()  # (V, 3)
        self.pairs = crossing_pairs(self.vertices, self.triangles, self.source)  # (P, 2)

    def faces(self) -> BoolArray:
        """(F,) which faces cross another at the current positions."""
        out = np.zeros(self.n_faces, dtype=bool)
        out[self.source[self.pairs.reshape(-1)]] = True
        return out

    def move(self, positions: FloatArray) -> BoolArray:
        """Move the vertices to ``positions`` (``(V, 3)``) and return :meth:`faces`."""
        positions = np.asarray(positions, dtype=np.float64)
        moved = np.any(positions != self.vertices, axis=1)  # (V,)
        self.vertices = positions.copy()
        if not moved.any() or len(self.triangles) < 2:
            return self.faces()
        triangles = self.triangles
        if not self.mesh.is_triangle_mesh():  # a polygon's triangles follow its shape
            triangles, _ = triangles_of(self.mesh.with_vertices(positions))
        if not np.array_equal(triangles, self.triangles):
            self.triangles = triangles
            self.pairs = crossing_pairs(positions, self.triangles, self.source)
            return self.faces()
        touched = moved[self.triangles].any(axis=1)  # (T,)
        if touched.mean() > FULL_RETEST_SHARE:  # the same answer, found faster in one go
            self.pairs = crossing_pairs(positions, self.triangles, self.source)
            return self.faces()
        kept = self.pairs[~(touched[self.pairs[:, 0]] | touched[self.pairs[:, 1]])]
        fresh = crossing_pairs(positions, self.triangles, self.source,
                               among=np.flatnonzero(touched))
        self.pairs = np.concatenate([kept, fresh])
        return self.faces()


def pairs_cross(vertices: FloatArray, triangles: IntArray, i: IntArray, j: IntArray,
                floor: float = 0.0) -> BoolArray:
    """Which of the triangle pairs ``(i[m], j[m])`` intersect, by the rules of
    :func:`intersecting_triangles`: two triangles on one corner cross when a ray from it
    lies in both (:func:`_one_corner_cross`), two on one edge when folded onto each
    other (:data:`FOLDED_COSINE`, whatever the gap between them), two on the same three
    corners always, and two that share no corner when closer than
    :data:`TOUCHING_SHARE` of the pair's own extent (so a pair's verdict depends on its
    six corners alone).

    Parameters
    ----------
    vertices : (V, 3) float
    triangles : (T, 3) int
    i, j : (M,) int
        Indices into ``triangles`` (``i[m] != j[m]``).
    floor : float
        The touching distance is at least this (0: each pair's own alone); two triangles
        on one corner then also touch when they come this close away from it (their
        copies shrunk by :data:`NEAR_SHRINK`).

    Returns
    -------
    (M,) bool
    """
    crossing = np.zeros(len(i), dtype=bool)
    if len(i) == 0:
        return crossing
    corners = vertices[triangles]  # (T, 3, 3)
    same = triangles[i][:, :, None] == triangles[j][:, None, :]  # (M, 3, 3)
    common = same.sum(axis=(1, 2))
    # triangles on one edge meet elsewhere only when folded onto each other, and then
    # they cross however thin the gap between them (a fin)
    normal = unit_rows(triangle_normals(corners))
    folded = np.einsum("md,md->m", normal[i], normal[j]) < -FOLDED_COSINE
    crossing[(common == 2) & folded] = True
    crossing[common == 3] = True  # one triangle twice (a two-face pillow): they coincide
    one = np.flatnonzero(common == 1)
    if len(one):
        crossing[one] = _one_corner_cross(corners[i[one]], corners[j[one]],
                                          same[one].any(axis=2).argmax(axis=1),
                                          same[one].any(axis=1).argmax(axis=1))
    if floor > 0:  # near contacts of the pairs on one corner, away from it
        near = one[~crossing[one]]
        ta, tb = _shrunk(corners[i[near]]), _shrunk(corners[j[near]])
        crossing[near[triangle_pairs_intersect(ta, tb, floor)]] = True
    apart = np.flatnonzero(common == 0)
    ta, tb = corners[i[apart]], corners[j[apart]]
    extent = _spread(np.concatenate([ta, tb], axis=1))  # (K,) the pair's extent
    eps = np.maximum(TOUCHING_SHARE * np.where(extent > 0, extent, 1.0), floor)
    crossing[apart[triangle_pairs_intersect(ta, tb, eps)]] = True
    return crossing


def _shrunk(corners: FloatArray) -> FloatArray:
    """Triangles ``corners`` ``(M, 3, 3)`` shrunk by :data:`NEAR_SHRINK` towards their
    centres."""
    centre = corners.mean(axis=1, keepdims=True)
    return centre + (corners - centre) * (1.0 - NEAR_SHRINK)


def _in_cone(ray: FloatArray, first: FloatArray, second: FloatArray, normal: FloatArray
             ) -> BoolArray:
    """``(M,)`` whether unit ``ray`` lies inside the cone of unit ``first`` and ``second``
    (a triangle's corner, under 180 degrees; ``normal`` ``first x second``, unit), by
    more than :data:`TOUCHING_SHARE`: a ray along a side does not count (all ``(M, 3)``).
    """
    return ((np.einsum("md,md->m", cross_rows(first, ray), normal) > TOUCHING_SHARE)
            & (np.einsum("md,md->m", cross_rows(ray, second), normal) > TOUCHING_SHARE))


def _one_corner_cross(ta: FloatArray, tb: FloatArray, ka: IntArray, kb: IntArray
                      ) -> BoolArray:
    """``(M,)`` whether triangles ``ta`` and ``tb`` (``(M, 3, 3)``), which share the
    corner ``ta[m, ka[m]] == tb[m, kb[m]]`` and no other, meet anywhere else.

    Their intersection is convex and holds the corner, so they meet elsewhere exactly
    when a ray from the corner lies in both: along the line where their planes meet, or,
    when they are coplanar (within :data:`COPLANAR_TOLERANCE`), when their corners'
    cones overlap, which one of the six rays of their sides and bisectors then shows.
    The test is exact at any scale: a crossing however thin counts, and the corner
    alone never does (the shrink of such pairs that it replaced hid crossings thinner
    than the shrink; docs/GEOMETRY.md, "One corner"). A ray along a side of either is
    not enough: sides that lie along each other (a polygon's corner on the straight side
    of its neighbour, whose triangles then meet along it) are not a crossing.
    """
    rows = np.arange(len(ta))[:, None]

    def cone(t: FloatArray, k: IntArray) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
        turn = t[rows, (k[:, None] + np.arange(3)) % 3]  # (M, 3, 3) the corner first
        first, second = unit_rows(turn[:, 1] - turn[:, 0]), unit_rows(turn[:, 2] - turn[:, 0])
        normal = cross_rows(first, second)
        return first, second, unit_rows(normal), np.any(normal != 0, axis=1)

    a1, a2, na, good_a = cone(ta, ka)
    b1, b2, nb, good_b = cone(tb, kb)
    coplanar = (np.maximum(np.abs(np.einsum("md,md->m", b1, na)),
                           np.abs(np.einsum("md,md->m", b2, na))) <= COPLANAR_TOLERANCE) & (
        np.maximum(np.abs(np.einsum("md,md->m", a1, nb)),
                   np.abs(np.einsum("md,md->m", a2, nb))) <= COPLANAR_TOLERANCE)
    line = unit_rows(cross_rows(na, nb))  # (M, 3) where their planes meet
    # every ray against its cone in one call: the line both ways in each cone (meet),
    # then each one's sides and bisector in the other's (overlap, when coplanar)
    m = len(ta)
    rays = np.concatenate([line, -line, line, -line, a1, a2, unit_rows(a1 + a2),
                           b1, b2, unit_rows(b1 + b2)])  # (10 M, 3)
    cones = [(a1, a2, na)] * 2 + [(b1, b2, nb)] * 5 + [(a1, a2, na)] * 3
    inside = _in_cone(rays, *(np.concatenate(part) for part in zip(*cones, strict=True))
                      ).reshape(10, m)
    meet = ((inside[0] & inside[2]) | (inside[1] & inside[3]))
    overlap = inside[4:].any(axis=0)
    return np.where(coplanar, overlap, meet) & good_a & good_b


def self_intersecting_faces(mesh: PolygonMesh, *, whole_extent: bool = False
                            ) -> BoolArray:
    """Which polygon faces of ``mesh`` intersect another face.

    Parameters
    ----------
    mesh : PolygonMesh
    whole_extent : bool
        Near contacts count too (:func:`near_contact_faces`).

    Returns
    -------
    (F,) bool
    """
    faces = np.zeros(mesh.n_faces, dtype=bool)
    if mesh.n_faces < 2:
        return faces
    triangles, source = triangles_of(mesh)
    hit = intersecting_triangles(mesh.vertices, triangles, source, whole_extent=whole_extent)
    faces[source[hit]] = True
    return faces


def near_contact_faces(mesh: PolygonMesh) -> BoolArray:
    """Which polygon faces of ``mesh`` intersect or nearly touch another face: within
    :data:`TOUCHING_SHARE` of the extent of the whole mesh (:func:`touching_eps`), not
    only of the pair's own as in :func:`self_intersecting_faces`. Two faces that close
    are one rounding away from crossing in another tool; the seeds' check
    (:func:`spacemesh.runtime.choice.acceptable`) sends more seeds for them.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    (F,) bool
    """
    return self_intersecting_faces(mesh, whole_extent=True)


def crossing_faces(mesh: PolygonMesh, among: BoolArray) -> IntArray:
    """The faces of ``among`` ((F,) bool) that cross a face of ``mesh`` (of ``among`` or
    not), by the exact test (:func:`spacemesh.geometry.intersections.crossing_pairs` from
    their triangles, among the faces whose bounding boxes meet the box of ``among``: its
    cost grows with ``among``, not with the mesh). Sorted face indices (K,)."""
    if not among.any():
        return np.zeros(0, dtype=np.int64)
    corners = mesh.vertices[mesh.face_indices]  # (C, 3)
    starts = mesh.face_offsets[:-1]
    low = np.minimum.reduceat(corners, starts, axis=0)  # (F, 3) each face's box
    high = np.maximum.reduceat(corners, starts, axis=0)
    near = np.flatnonzero(np.all(high >= low[among].min(axis=0), axis=1)
                          & np.all(low <= high[among].max(axis=0), axis=1))  # (N,)
    local = np.zeros(mesh.n_faces, dtype=bool)
    local[near] = True
    triangles, source = triangles_of(faces_subset(mesh, local))  # source: into ``near``
    pairs = crossing_pairs(mesh.vertices, triangles, source,
                           among=np.flatnonzero(among[near][source]))  # (P, 2)
    faces = near[np.unique(source[pairs.reshape(-1)])]
    return faces[among[faces]]


def self_intersection_fraction(mesh: PolygonMesh) -> float:
    """The fraction (in [0, 1]) of faces that intersect another face (0 for no faces)."""
    if mesh.n_faces == 0:
        return 0.0
    return float(self_intersecting_faces(mesh).mean())
