"""The piecewise-planar continuation of a sharp ring: a hole across a crease, a corner
or a thin wall is continued by the planes of the flat clusters of faces around it
(:func:`planar_positions`), the candidate the fairing weighs against the smooth ones
(:func:`spacemesh.repair.fill.fairing.fair_patch`).

numpy and scipy only.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    edge_keys,
    faces_subset,
    faces_touching,
    triangulate_faces,
    unit_rows,
    vertices_of,
)
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Faces around a patch whose normals are within this angle (degrees) of a cluster's
#: mean normal join that cluster (:func:`ring_planes`).
CLUSTER_ANGLE = 30.0
#: A ring is sharp when two of its clusters' normals are this far apart (degrees).
SHARP_ANGLE = 60.0
#: A cluster is planar when the RMS distance of its vertices to their plane is below
#: this share of their RMS spread along the plane (a low-poly curved surface is not).
FLATNESS = 0.03
#: The clusters kept must hold at least this share of the ring faces' area (else the
#: ring also crosses a curved part, such as a thin wall's rounded rim, that no plane
#: continues).
MIN_COVERAGE = 0.9
#: Clusters with less than this share of the ring faces' area are ignored.
MIN_CLUSTER_SHARE = 0.08


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
    key = edge_keys(he, mesh.n_vertices)
    key, face = key[inside], mesh.face_of_corner[inside]
    order = np.argsort(key, kind="stable")
    key, face = key[order], face[order]
    pair = np.flatnonzero(key[1:] == key[:-1])
    cos = np.einsum("ij,ij->i", normal[face[pair]], normal[face[pair + 1]])
    return bool((cos < math.cos(math.radians(SHARP_ANGLE))).any())


def ring_planes(mesh: PolygonMesh, free: BoolArray, patch: BoolArray
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
    normal = np.zeros((mesh.n_faces, 3))  # only the ring faces' are read
    normal[faces] = faces_subset(mesh, faces).face_normals()
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
    units = unit_rows(np.asarray(sums)[big])
    if (len(big) < 2 or share[big].sum() < MIN_COVERAGE
            or not _has_crease(mesh, faces, normal)):
        return None
    normals, points = [], []
    for which, unit in zip(big, units, strict=True):
        corners = np.unique(mesh.face_indices[(cluster == which)[mesh.face_of_corner]])
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
    or a thin wall), or None when the ring is smooth (:func:`ring_planes`).

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
        those of :func:`ring_planes`.

    Returns
    -------
    (V, 3) float64 or None
    """
    if planes is None:
        found = ring_planes(mesh, free, patch)
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
