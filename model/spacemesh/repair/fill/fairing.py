"""Hole patches made to continue the surface around them (Liepa, "Filling holes in
meshes", SGP 2003).

A filled hole's new vertices are first placed where its filling put them (a fan, the
model's wedges), which on a curved surface is a flat or folded patch. Here the patch is

1. **refined** (:func:`refine_patch`): its large polygons are fanned from their
   centroid, every interior edge of its triangles longer than :data:`SPLIT_RATIO`
   times the target length (the mean length of the hole's boundary edges) is split at
   its midpoint, both triangles on it in two, then its interior edges are flipped
   towards Delaunay triangles, so that the patch has the density of the surface around
   it; quads, pentagons and the hole's boundary edges are never split;
2. **faired** (:func:`fair_positions`): its vertices are moved to the solution of the
   discrete tri-Laplace equation ``L^3 x = 0`` or bi-Laplace equation ``L^2 x = 0``
   (cotangent weights, re-read once from the first solution) with every other vertex
   fixed: the boundary ring and the rings of faces beyond it define the position, the
   slope and (tri-harmonic) the curvature the patch continues (a sparse solve); uniform
   weights or a membrane (``L x = 0``, within the hull of the ring), and around a sharp ring
   (flat clusters of faces meeting at a crease) a piecewise-planar continuation
   (:func:`planar_positions`), are the other candidates; the one kept
   (:func:`_continuation`) best predicts the ring itself when the ring is freed too,
   measured against the input's surface around it (a tri-harmonic or thin-plate
   surface that overshoots the box of the ring, as over a hole across sharp edges, is
   never kept; when all of them overshoot, the membrane is projected onto the
   least-area triangulation of the hole's loops, :func:`flat_positions`, the flat fill
   MeshFix-like tools make);
3. **guarded** (:func:`fair_patch`): the faired positions are kept only where they make no
   new self-intersection near the patch (the move is halved up to twice, else undone).

numpy and scipy only; no face outside the patch changes, and its topology is kept.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import MatrixRankWarning, spsolve

from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset, faces_touching, triangulate_faces, vertices_of
from spacemesh.primitives.closest import closest_points_on_triangles
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: An interior patch edge longer than this times the target length is split.
SPLIT_RATIO = math.sqrt(2.0)
#: Most vertices a refinement adds, as a multiple of the patch's area over that of an
#: equilateral triangle of the target edge (bounds the work).
MAX_DENSITY = 2.0
#: Most rounds of splits (each splits every long edge whose triangles are untouched).
MAX_ROUNDS = 24
#: Patch polygons with at least this many corners (the splice's last resort, one
#: polygon over a loop the model could not fill) are fanned from their centroid first.
FAN_CORNERS = 6
#: Sweeps of Delaunay flips after the splits.
FLIP_SWEEPS = 4
#: Bounds of the cotangent weights of :func:`fair_positions` (obtuse angles give
#: negative cotangents, slivers huge ones).
MIN_COTANGENT, MAX_COTANGENT = 1e-3, 1e2
#: Solves of :func:`fair_positions` (the weights re-read from the last solution).
FAIR_SOLVES = 2
#: How far (a share of the largest side of the box of the fixed vertices around a
#: patch) a faired vertex may leave that box before a gentler fairing is used.
MAX_OVERSHOOT = 0.1
#: Faces around a patch whose normals are within this angle (degrees) of a cluster's
#: mean normal join that cluster (:func:`_ring_planes`).
CLUSTER_ANGLE = 30.0
#: A ring is sharp when two of its clusters' normals are this far apart (degrees).
SHARP_ANGLE = 60.0
#: A cluster is planar when the RMS distance of its vertices to their plane is below
#: this share of their RMS spread along the plane (a low-poly curved surface is not).
FLATNESS = 0.03
#: A gentler smooth fairing is used when its ring error is below this share of the
#: stiffer one's (:func:`_continuation`).
SMOOTH_MARGIN = 0.9
#: The planar continuation is used when its ring error is below this share of the
#: smooth fairing's (:func:`_continuation`).
PLANAR_MARGIN = 0.5
#: Rings of faces around a patch whose surface its freed ring is measured against.
SURFACE_RINGS = 3
#: The clusters kept must hold at least this share of the ring faces' area (else the
#: ring also crosses a curved part, such as a thin wall's rounded rim, that no plane
#: continues).
MIN_COVERAGE = 0.9
#: Clusters with less than this share of the ring faces' area are ignored.
MIN_CLUSTER_SHARE = 0.08
#: Longest loop the minimal-area triangulation of :func:`flat_positions` is built for
#: (its dynamic programme takes ``O(n^3)`` work); a longer one keeps the membrane.
MAX_FLAT_LOOP = 300
#: Triangles (nearest by centroid) each vertex is projected onto in :func:`flat_positions`.
FLAT_NEIGHBOURS = 8


# ---------------------------------------------------------------------- refinement
def _edge_key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


def _opposite_angle(p: FloatArray, a: int, b: int, c: int) -> float:
    """The angle at ``c`` of the triangle ``a b c``."""
    u, v = p[a] - p[c], p[b] - p[c]
    cos = float(u @ v) / max(float(np.linalg.norm(u) * np.linalg.norm(v)), 1e-300)
    return math.acos(min(1.0, max(-1.0, cos)))


class _Triangles:
    """The patch's triangles as a mutable list with an edge -> triangles map."""

    def __init__(self, triangles: list[list[int]], taken: set[tuple[int, int]]) -> None:
        self.taken = taken  # edges of the faces outside the patch (never made by a flip)
        self.tris: list[list[int] | None] = [list(t) for t in triangles]
        self.edges: dict[tuple[int, int], list[int]] = {}
        for t, tri in enumerate(self.tris):
            self._link(t, tri)

    def _link(self, t: int, tri: list[int]) -> None:
        for k in range(3):
            self.edges.setdefault(_edge_key(tri[k], tri[(k + 1) % 3]), []).append(t)

    def _unlink(self, t: int) -> None:
        tri = self.tris[t]
        assert tri is not None
        for k in range(3):
            key = _edge_key(tri[k], tri[(k + 1) % 3])
            self.edges[key].remove(t)
            if not self.edges[key]:
                del self.edges[key]
        self.tris[t] = None

    def replace(self, old: list[int], new: list[list[int]]) -> None:
        for t in old:
            self._unlink(t)
        for tri in new:
            self.tris.append(tri)
            self._link(len(self.tris) - 1, tri)

    def interior(self) -> list[tuple[tuple[int, int], int, int]]:
        """Edges with a patch triangle on each side: (edge, triangle, triangle)."""
        return [(e, ts[0], ts[1]) for e, ts in self.edges.items() if len(ts) == 2]

    @staticmethod
    def apex(tri: list[int], a: int, b: int) -> tuple[int, bool]:
        """The corner of ``tri`` off the edge ``a b``, and whether ``tri`` runs ``a -> b``."""
        k = tri.index(a)
        forward = tri[(k + 1) % 3] == b
        return tri[(k + 2) % 3] if forward else tri[(k + 1) % 3], forward

    def alive(self) -> list[list[int]]:
        return [t for t in self.tris if t is not None]


def _split_pass(tris: _Triangles, positions: list[FloatArray], limit: float,
                budget: int) -> int:
    """Split the interior edges longer than ``limit`` (longest first); returns the
    vertices added."""
    p = np.asarray(positions)
    long = [(float(np.linalg.norm(p[e[0]] - p[e[1]])), e) for e, _, _ in tris.interior()]
    long = sorted((x for x in long if x[0] > limit), reverse=True)
    touched: set[int] = set()
    added = 0
    for _, (a, b) in long:
        if added >= budget:
            break
        ts = tris.edges.get((a, b), [])
        if len(ts) != 2 or touched & set(ts):
            continue
        tri_a, tri_b = tris.tris[ts[0]], tris.tris[ts[1]]
        assert tri_a is not None and tri_b is not None
        if not _Triangles.apex(tri_a, a, b)[1]:
            tri_a, tri_b = tri_b, tri_a
        c, _ = _Triangles.apex(tri_a, a, b)  # a -> b -> c
        d, _ = _Triangles.apex(tri_b, a, b)  # b -> a -> d
        m = len(positions)
        positions.append((p[a] + p[b]) / 2.0)
        touched.update(ts)
        tris.replace(list(ts), [[a, m, c], [m, b, c], [b, m, d], [m, a, d]])
        touched.update(range(len(tris.tris) - 4, len(tris.tris)))
        added += 1
    return added


def _flip_pass(tris: _Triangles, p: FloatArray) -> int:
    """Flip interior edges whose opposite angles sum beyond pi (Delaunay); returns the
    flips made."""
    flips = 0
    for (a, b), _, _ in tris.interior():
        ts = tris.edges.get((a, b), [])
        if len(ts) != 2:
            continue
        tri_a, tri_b = tris.tris[ts[0]], tris.tris[ts[1]]
        assert tri_a is not None and tri_b is not None
        if not _Triangles.apex(tri_a, a, b)[1]:
            tri_a, tri_b = tri_b, tri_a
        c, _ = _Triangles.apex(tri_a, a, b)
        d, _ = _Triangles.apex(tri_b, a, b)
        if c == d or _edge_key(c, d) in tris.edges or _edge_key(c, d) in tris.taken:
            continue
        if _opposite_angle(p, a, b, c) + _opposite_angle(p, a, b, d) <= math.pi + 1e-9:
            continue
        tris.replace(list(ts), [[a, d, c], [d, b, c]])
        flips += 1
    return flips


def refine_patch(mesh: PolygonMesh, patch: BoolArray, target: float
                 ) -> tuple[PolygonMesh, IntArray]:
    """Split the long interior edges of the patch's triangles and flip towards Delaunay.

    Parameters
    ----------
    mesh : PolygonMesh
    patch : (F,) bool
        The patch's faces; only its triangles are refined, and only along edges with a
        patch triangle on both sides (its boundary and its quads and pentagons stay as
        they are); its polygons of :data:`FAN_CORNERS` or more corners are first fanned
        from a new vertex at their centroid.
    target : float
        The edge length aimed at; edges longer than :data:`SPLIT_RATIO` times it are split.

    Returns
    -------
    mesh : PolygonMesh
        The input's vertices then the new ones (centroids, midpoints); the faces not
        refined in their order, then the patch's triangles.
    face_source : (F',) int64
        The input face of each face (-1 for the refined triangles).
    """
    sizes = mesh.face_sizes
    tri_faces = np.flatnonzero(patch & ((sizes == 3) | (sizes >= FAN_CORNERS)))
    if len(tri_faces) == 0 or not target > 0:
        return mesh, np.arange(mesh.n_faces)
    positions = list(mesh.vertices)
    triangles: list[list[int]] = []
    for f in tri_faces:
        corners = mesh.face_indices[mesh.face_offsets[f]:mesh.face_offsets[f + 1]].tolist()
        if len(corners) == 3:
            triangles.append(corners)
            continue
        centre = len(positions)  # a large polygon becomes a fan from its centroid
        positions.append(mesh.vertices[corners].mean(axis=0))
        triangles += [[a, b, centre] for a, b in zip(corners, np.roll(corners, -1).tolist(),
                                                     strict=True)]
    outside = np.ones(mesh.n_faces, dtype=bool)
    outside[tri_faces] = False
    tris = _Triangles(triangles, {_edge_key(a, b) for a, b in
                                  faces_subset(mesh, outside).edges.tolist()})
    corners = np.asarray(positions)[np.asarray(triangles)]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1).sum()
    budget = int(MAX_DENSITY * area / (math.sqrt(3) / 4 * target**2)) + 1
    added = 0
    for _ in range(MAX_ROUNDS):
        if added >= budget:
            break
        step = _split_pass(tris, positions, SPLIT_RATIO * target, budget - added)
        if step == 0:
            break
        added += step
        _flip_pass(tris, np.asarray(positions))
    if added == 0 and len(positions) == mesh.n_vertices:
        return mesh, np.arange(mesh.n_faces)
    p = np.asarray(positions)
    for _ in range(FLIP_SWEEPS):
        if _flip_pass(tris, p) == 0:
            break
    keep = np.ones(mesh.n_faces, dtype=bool)
    keep[tri_faces] = False
    kept = np.flatnonzero(keep)
    new = np.asarray(tris.alive(), dtype=np.int64)
    kept_mesh = faces_subset(mesh, keep)
    indices = np.concatenate([kept_mesh.face_indices, new.reshape(-1)])
    offsets = np.concatenate([kept_mesh.face_offsets,
                              kept_mesh.face_offsets[-1] + 3 * np.arange(1, len(new) + 1)])
    out = PolygonMesh(p, indices, offsets.astype(np.int64))
    source = np.concatenate([kept, np.full(len(new), -1)]).astype(np.int64)
    return out, source


# ---------------------------------------------------------------------- fairing


def _laplacian(mesh: PolygonMesh, faces: BoolArray, uniform: bool = False) -> sp.csr_matrix:
    """``I - D^-1 W`` over the faces ``faces`` (each polygon fanned into triangles), with
    cotangent weights ``W`` clamped to [:data:`MIN_COTANGENT`, :data:`MAX_COTANGENT`] (a
    cotangent Laplacian measures the curvature of the fixed ring however its edges are
    laid out, where uniform weights would read an anisotropic ring as curved), or with
    ``uniform`` weights 1 on every edge, (V, V)."""
    triangles, _ = triangulate_faces(faces_subset(mesh, faces))
    p = np.asarray(mesh.vertices, dtype=np.float64)
    n = mesh.n_vertices
    rows, cols, weights = [], [], []
    for k in range(3):
        i, j, o = triangles[:, k], triangles[:, (k + 1) % 3], triangles[:, (k + 2) % 3]
        u, v = p[i] - p[o], p[j] - p[o]
        sine = np.linalg.norm(np.cross(u, v), axis=1)
        cot = np.einsum("ij,ij->i", u, v) / np.maximum(sine, 1e-300)
        cot = np.clip(np.where(sine > 0, cot, MAX_COTANGENT), MIN_COTANGENT, MAX_COTANGENT)
        rows += [i, j]
        cols += [j, i]
        weights += [cot / 2, cot / 2]
    w = sp.coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
    if uniform:
        w.data[:] = 1.0
    degree = np.asarray(w.sum(axis=1)).ravel()
    inverse = sp.diags(np.where(degree > 0, 1.0 / np.maximum(degree, 1e-300), 0.0))
    return (sp.identity(n, format="csr") - inverse @ w).tocsr()




def fair_positions(mesh: PolygonMesh, free: BoolArray, order: int = 2,
                   weights: str = "cotangent") -> FloatArray:
    """Positions with the ``free`` vertices solving ``L^order x = 0``, the rest fixed.

    ``order`` 1 is a membrane (each free vertex at the mean of its neighbours), 2 a
    thin plate, whose boundary conditions are the fixed ring and the ring beyond it, 3
    the tri-harmonic surface, which reads a third ring and continues the curvature.
    Only the faces within ``order`` rings of the free vertices are read. A free part
    that no fixed vertex reaches keeps its positions.

    Parameters
    ----------
    mesh : PolygonMesh
    free : (V,) bool
    order : {1, 2, 3}
    weights : {"cotangent", "uniform"}
        Cotangent weights (re-read from the first solution, :data:`FAIR_SOLVES` solves)
        or the uniform umbrella (one solve).

    Returns
    -------
    (V, 3) float64
    """
    positions = np.asarray(mesh.vertices, dtype=np.float64).copy()
    if not free.any():
        return positions
    near = free.copy()
    for _ in range(order - 1):
        near |= vertices_of(mesh, faces_touching(mesh, near))
    faces = faces_touching(mesh, near)
    rows = np.flatnonzero(free)
    fixed = ~free
    for _ in range(FAIR_SOLVES if weights == "cotangent" else 1):
        lap = _laplacian(mesh.with_vertices(positions), faces, weights == "uniform")
        system = lap
        for _ in range(order - 1):
            system = lap @ system
        a = system[rows][:, rows].tocsc()
        rhs = -(system[rows][:, fixed] @ positions[fixed])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", MatrixRankWarning)
                solved = np.asarray(spsolve(a, rhs)).reshape(len(rows), 3)
        except (RuntimeError, MatrixRankWarning):  # singular: a part no fixed vertex reaches
            break
        if not np.isfinite(solved).all():
            break
        positions[rows] = solved
    return positions




def boundary_edge_length(mesh: PolygonMesh, loops: list[IntArray]) -> float:
    """Mean length of the edges of the closed ``loops`` (vertex cycles)."""
    lengths = [np.linalg.norm(mesh.vertices[loop] - mesh.vertices[np.roll(loop, -1)], axis=1)
               for loop in loops if len(loop) > 1]
    return float(np.concatenate(lengths).mean()) if lengths else 0.0


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


def _triangle_areas(mesh: PolygonMesh, faces: BoolArray) -> FloatArray:
    """The area of every face (0 for those not in ``faces``), (F,)."""
    triangles, source = triangulate_faces(faces_subset(mesh, faces))
    corners = mesh.vertices[triangles]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1)
    out = np.zeros(mesh.n_faces)
    np.add.at(out, np.flatnonzero(faces)[source], area)
    return out


def _has_crease(mesh: PolygonMesh, faces: BoolArray, normal: FloatArray) -> bool:
    """Whether two of the ``faces`` sharing an edge meet at more than
    :data:`SHARP_ANGLE` (a dihedral crease, not a smooth curve)."""
    he = mesh.halfedges
    inside = faces[mesh.face_of_corner]
    key = np.minimum(he[:, 0], he[:, 1]) * mesh.n_vertices + np.maximum(he[:, 0], he[:, 1])
    key, face = key[inside], mesh.face_of_corner[inside]
    order = np.argsort(key, kind="stable")
    key, face = key[order], face[order]
    pair = np.flatnonzero(key[1:] == key[:-1])
    cos = np.einsum("ij,ij->i", normal[face[pair]], normal[face[pair + 1]])
    return bool((cos < math.cos(math.radians(SHARP_ANGLE))).any())


def _ring_planes(mesh: PolygonMesh, free: BoolArray, patch: BoolArray
                 ) -> tuple[FloatArray, FloatArray, IntArray, IntArray] | None:
    """The planes of the sharp ring around the ``free`` vertices, or None when it is
    smooth.

    The faces outside ``patch`` within two rings of the fixed vertices next to the free
    ones are clustered by normal (area first, each joining the first cluster within
    :data:`CLUSTER_ANGLE`); the ring is sharp when two clusters hold at least
    :data:`MIN_CLUSTER_SHARE` of their area each (and those hold
    :data:`MIN_COVERAGE` of it) and two of the faces meet at a crease
    (:func:`_has_crease`), and each cluster is flat (:data:`FLATNESS`). Each cluster
    gets the least-squares plane of its faces' vertices.

    Returns
    -------
    normals, points : (K, 3) float64
        A unit normal and a point of each cluster's plane.
    ring : (R,) int64
        The fixed vertices next to the free ones.
    label : (R,) int64
        The cluster of each (that of its largest clustered face).
    """
    inner = faces_touching(mesh, free)
    ring = vertices_of(mesh, inner) & ~free
    outside = ~patch & ~inner
    first = outside & faces_touching(mesh, ring)
    faces = first | (outside & faces_touching(mesh, vertices_of(mesh, first)))
    if not first.any():
        return None
    area = _triangle_areas(mesh, faces)
    normal = mesh.face_normals()
    ids = np.flatnonzero(faces)[np.argsort(-area[faces], kind="stable")]
    cos = math.cos(math.radians(CLUSTER_ANGLE))
    sums: list[FloatArray] = []
    cluster = np.full(mesh.n_faces, -1, dtype=np.int64)
    for f in ids:
        for k, total in enumerate(sums):
            if normal[f] @ total > cos * np.linalg.norm(total):
                cluster[f] = k
                sums[k] = total + area[f] * normal[f]
                break
        else:
            cluster[f] = len(sums)
            sums.append(area[f] * normal[f])
    share = np.bincount(cluster[faces], area[faces], minlength=len(sums)) / max(
        float(area[faces].sum()), 1e-300)
    big = np.flatnonzero(share >= MIN_CLUSTER_SHARE)
    units = np.asarray(sums)[big]
    units /= np.maximum(np.linalg.norm(units, axis=1, keepdims=True), 1e-300)
    if (len(big) < 2 or share[big].sum() < MIN_COVERAGE
            or not _has_crease(mesh, faces, normal)):
        return None
    normals, points = [], []
    for k, unit in zip(big, units, strict=True):
        corners = np.unique(mesh.face_indices[(cluster == k)[mesh.face_of_corner]])
        x = mesh.vertices[corners]
        centre = x.mean(axis=0)
        _, spread, vt = np.linalg.svd(x - centre, full_matrices=False)
        if len(x) < 3 or spread[-1] > FLATNESS * spread[0]:
            return None  # a curved cluster: the smooth fairing continues it
        fitted = vt[-1]
        normals.append(fitted if fitted @ unit >= 0 else -fitted)
        points.append(centre)
    # each ring vertex: the cluster of its largest face among the big clusters
    remap = np.full(len(sums) + 1, -1, dtype=np.int64)
    remap[big] = np.arange(len(big))
    ring_ids = np.flatnonzero(ring)
    corner_face = mesh.face_of_corner
    vertex = mesh.face_indices
    keep = faces[corner_face] & ring[vertex] & (remap[cluster[corner_face]] >= 0)
    label = np.full(mesh.n_vertices, -1, dtype=np.int64)
    for c in np.flatnonzero(keep)[np.argsort(area[corner_face[keep]], kind="stable")]:
        label[vertex[c]] = remap[cluster[corner_face[c]]]
    labelled = ring_ids[label[ring_ids] >= 0]
    if len(labelled) == 0:
        return None
    return np.asarray(normals), np.asarray(points), labelled, label[labelled]


def planar_positions(mesh: PolygonMesh, free: BoolArray, patch: BoolArray,
                     base: FloatArray, planes: tuple[FloatArray, FloatArray] | None = None
                     ) -> FloatArray | None:
    """A piecewise-planar continuation of a sharp ring (a hole across a crease, a corner
    or a thin wall), or None when the ring is smooth (:func:`_ring_planes`).

    Each free vertex takes the plane of the ring vertex nearest to it along the edges of
    the faces around the free vertices (a graph distance, so the patch is split along
    the crease), and its ``base`` position is projected onto that plane.

    Parameters
    ----------
    mesh : PolygonMesh
    free : (V,) bool
    patch : (F,) bool
        The faces of the filled hole(s) (never read as the surface around it).
    base : (V, 3) float64
        Positions to project (for example a membrane, within the hull of the ring).
    planes : (normals, points), optional
        Given planes (each ring vertex then takes the plane nearest to it) instead of
        those of :func:`_ring_planes`.

    Returns
    -------
    (V, 3) float64 or None
    """
    from scipy.sparse.csgraph import dijkstra

    if planes is None:
        found = _ring_planes(mesh, free, patch)
        if found is None:
            return None
        normals, points, ring, label = found
    else:
        normals, points = planes
        ring = np.flatnonzero(vertices_of(mesh, faces_touching(mesh, free)) & ~free)
        offsets = np.abs(np.einsum("kd,rkd->rk", normals,
                                   mesh.vertices[ring][:, None] - points[None]))
        label = offsets.argmin(axis=1)
    local = faces_subset(mesh, faces_touching(mesh, free))
    edges = local.edges
    length = np.linalg.norm(base[edges[:, 0]] - base[edges[:, 1]], axis=1) + 1e-12
    n = mesh.n_vertices
    graph = sp.coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    _, _, nearest = dijkstra(graph, directed=False, indices=ring, min_only=True,
                             return_predecessors=True)
    rows = np.flatnonzero(free)
    source = nearest[rows]
    reached = source >= 0
    lookup = np.full(n, -1, dtype=np.int64)
    lookup[ring] = label
    k = lookup[np.where(reached, source, 0)]
    ok = reached & (k >= 0)
    out = np.asarray(base, dtype=np.float64).copy()
    x, nk, pk = out[rows[ok]], normals[k[ok]], points[k[ok]]
    x = x - np.einsum("ij,ij->i", x - pk, nk)[:, None] * nk
    out[rows[ok]] = _clip_to_creases(x, k[ok], normals, points)
    return out


def _clip_to_creases(x: FloatArray, k: IntArray, normals: FloatArray,
                     points: FloatArray) -> FloatArray:
    """Points ``x`` on the planes ``k`` moved onto the crease line with any other plane
    they pass: beyond it at a convex crease (where the solid is the intersection of the
    two half-spaces), behind it at a concave one (their union). Near-parallel planes
    (a thin wall's two sides) have no crease."""
    x = x.copy()
    for a in range(len(normals)):
        mine = k == a
        for b in range(len(normals)):
            cos = float(normals[a] @ normals[b])
            if b == a or abs(cos) > 0.95 or not mine.any():
                continue
            convex = float(normals[a] @ (points[b] - points[a])) < 0
            side = (x[mine] - points[b]) @ normals[b]
            wrong = side > 0 if convex else side < 0
            # along plane a, towards plane b: the direction of n_b within plane a
            along = normals[b] - cos * normals[a]
            step = side / (1.0 - cos * cos)
            moved = x[mine] - step[:, None] * along[None]
            x[np.flatnonzero(mine)[wrong]] = moved[wrong]
    return x


def _surface_distance(mesh: PolygonMesh, faces: BoolArray, x: FloatArray,
                      steps: int = 4) -> FloatArray:
    """Distance of each point ``x`` to the plane of the triangle of the ``faces`` of
    ``mesh`` nearest to it (found among points on a barycentric grid of ``steps`` per
    side on each triangle), (N,)."""
    from scipy.spatial import cKDTree

    triangles, _ = triangulate_faces(faces_subset(mesh, faces))
    i, j = np.meshgrid(np.arange(steps + 1), np.arange(steps + 1), indexing="ij")
    keep = i + j <= steps
    a, b = i[keep] / steps, j[keep] / steps
    bary = np.stack([1 - a - b, a, b], axis=1)  # (G, 3)
    corners = mesh.vertices[triangles]  # (T, 3, 3)
    samples = np.einsum("gk,tkd->tgd", bary, corners).reshape(-1, 3)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    nearest = cKDTree(samples).query(x)[1] // len(bary)
    return np.abs(np.einsum("ij,ij->i", x - corners[nearest, 0], normal[nearest]))


# ---------------------------------------------------------------------- flat fill
def min_area_triangles(points: FloatArray) -> IntArray:
    """The triangulation of a closed polygon of least total area (Liepa 2003, Sec. 3.1;
    the fill MeshFix-like tools start from), by dynamic programming over its sub-chains.

    Parameters
    ----------
    points : (n, 3) float
        The polygon's corners in order, ``n >= 3``.

    Returns
    -------
    (n - 2, 3) int64
        Corner indices of each triangle, in the polygon's direction.
    """
    n = len(points)
    p = np.asarray(points, dtype=np.float64)
    cost = np.zeros((n, n))
    best = np.zeros((n, n), dtype=np.int64)
    for length in range(2, n):
        for a in range(n - length):
            b = a + length
            k = np.arange(a + 1, b)
            area = 0.5 * np.linalg.norm(np.cross(p[k] - p[a], p[b] - p[a]), axis=1)
            total = cost[a, k] + cost[k, b] + area
            m = int(np.argmin(total))
            cost[a, b], best[a, b] = total[m], k[m]
    triangles, stack = [], [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a >= 2:
            k = int(best[a, b])
            triangles.append((a, k, b))
            stack += [(a, k), (k, b)]
    return np.asarray(triangles, dtype=np.int64).reshape(-1, 3)


def patch_loops(mesh: PolygonMesh, patch: BoolArray) -> list[IntArray] | None:
    """The loops of the patch's border (its edges with no patch face on the other side),
    in the patch's direction, or None when they are not simple cycles."""
    inside = patch[mesh.face_of_corner]
    he = mesh.halfedges[inside]
    n = max(mesh.n_vertices, 1)
    key = he[:, 0] * n + he[:, 1]
    border = he[~np.isin(he[:, 1] * n + he[:, 0], key)]
    if len(np.unique(border[:, 0])) != len(border):
        return None
    following = dict(zip(border[:, 0].tolist(), border[:, 1].tolist(), strict=True))
    loops, seen = [], set()
    for first in following:
        if first in seen:
            continue
        loop, v = [], first
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = following.get(v, -1)
            if v < 0:
                return None
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def flat_positions(mesh: PolygonMesh, free: BoolArray, patch: BoolArray, base: FloatArray
                   ) -> FloatArray | None:
    """The ``base`` positions of the ``free`` vertices projected onto the least-area
    triangulation of each of the patch's border loops (:func:`min_area_triangles`): a
    flat patch spanned by the loop (what MeshFix-like fillers make), with the patch's
    own tessellation; None when a loop is not simple or longer than
    :data:`MAX_FLAT_LOOP`."""
    from scipy.spatial import cKDTree

    loops = patch_loops(mesh, patch)
    if not loops or any(len(loop) > MAX_FLAT_LOOP for loop in loops):
        return None
    corners = np.concatenate([mesh.vertices[loop][min_area_triangles(mesh.vertices[loop])]
                              for loop in loops if len(loop) >= 3])  # (T, 3, 3)
    if len(corners) == 0:
        return None
    rows = np.flatnonzero(free)
    x = np.asarray(base, dtype=np.float64)[rows]
    k = min(FLAT_NEIGHBOURS, len(corners))
    _, near = cKDTree(corners.mean(axis=1)).query(x, k=k)
    near = np.asarray(near).reshape(len(rows), k)
    closest = closest_points_on_triangles(np.repeat(x, k, axis=0),
                                          corners[near.reshape(-1)]).reshape(len(rows), k, 3)
    pick = np.linalg.norm(closest - x[:, None], axis=2).argmin(axis=1)
    out = np.asarray(base, dtype=np.float64).copy()
    out[rows] = closest[np.arange(len(rows)), pick]
    return out


#: The smooth fairings tried, stiffest first, gentlest last: (order, weights) of
#: :func:`fair_positions`. The tri-harmonic ``L^3 x = 0`` also continues the curvature
#: of the surface around the hole (C2 where the thin plate is C1: Botsch & Kobbelt
#: 2004), which on the dev holes over smooth surfaces (a torus, spikes, a knight) came
#: closer to the intact surface, up to ten times; over sharp surroundings it
#: overshoots more, and the ring's box and ring score (:func:`_continuation`) then
#: keep a gentler one.
SMOOTH_FAIRINGS = ((3, "cotangent"), (2, "cotangent"), (2, "uniform"), (1, "uniform"))
#: Their names in reports.
FAIRING_NAMES = ("tri-harmonic", "thin-plate", "thin-plate-uniform", "membrane")


def _continuation(mesh: PolygonMesh, free: BoolArray, patch: BoolArray,
                  start: FloatArray) -> tuple[FloatArray, float, str]:
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
    the membrane is replaced by the flat fill (:func:`flat_positions`: closer to the
    intact surface on every such dev hole). ``start`` when no candidate stays within the box.

    Returns the positions, the ring error of the candidate kept (of the membrane for
    the flat fill; infinite for ``start``) and its name (:data:`FAIRING_NAMES`, ``flat``,
    ``planar`` or ``none``)."""
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

    best, best_error, kind = start, math.inf, "none"
    plate = False  # whether a tri-harmonic or thin-plate surface stays within the box
    for (order, weights), name in zip(SMOOTH_FAIRINGS, FAIRING_NAMES, strict=True):
        faired = fair_positions(mesh, free, order, weights)
        if not _contained(mesh, free, start, faired):
            continue
        plate |= order >= 2
        error = score(fair_positions(mesh, wider, order, weights))
        if error < SMOOTH_MARGIN * best_error:
            best, best_error, kind = faired, error, name
    if not plate:  # sharp surroundings: the flat least-area fill rather than a membrane
        flat = flat_positions(mesh, free, patch, best)
        if flat is not None:
            best, kind = flat, "flat"
    found = _ring_planes(mesh, free, patch)
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
        return planar, planar_error, "planar"
    return best, best_error, kind


def patch_edge_length(mesh: PolygonMesh, patch: BoolArray) -> float:
    """Mean length of the edges on the patch's border (one side in the patch, the other
    outside it): the density of the surface around the patch (0 without such edges)."""
    he = mesh.halfedges
    inside = patch[mesh.face_of_corner]
    key = np.minimum(he[:, 0], he[:, 1]) * mesh.n_vertices + np.maximum(he[:, 0], he[:, 1])
    _, edge, count = np.unique(key, return_inverse=True, return_counts=True)
    sides = np.bincount(edge, inside, minlength=len(count))
    border = (count[edge] == 2) & inside & (sides[edge] == 1)
    if not border.any():
        return 0.0
    p = mesh.vertices
    return float(np.linalg.norm(p[he[border, 0]] - p[he[border, 1]], axis=1).mean())


def fair_patch(mesh: PolygonMesh, patch: BoolArray, free: BoolArray, target: float,
               *, refine: bool = True, report: dict | None = None
               ) -> tuple[PolygonMesh, IntArray, int]:
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
        ``fairing``, the name of that fairing, and ``weight``, the share of the move kept
        (1, or 0.5, 0.25 or 0 where the full move would add a self-intersection).

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
    faired, error, kind = _continuation(mesh, free, patch_after, start)
    if report is not None:
        report.update(ring_error=error, fairing=kind)
    near = faces_touching(mesh, vertices_of(mesh, faces_touching(mesh, free)))
    local = faces_subset(mesh, near)

    def crossings(positions: FloatArray) -> int:
        return int(self_intersecting_faces(local.with_vertices(positions)).sum())

    before = crossings(mesh.vertices)
    for weight in (1.0, 0.5, 0.25):
        moved = start + weight * (faired - start)
        if crossings(moved) <= before:
            if report is not None:
                report["weight"] = weight
            return mesh.with_vertices(moved), source, added
    if report is not None:
        report["weight"] = 0.0
    return mesh, source, added
