"""Self-intersecting faces with numpy and scipy only (the serving install has no
pymeshlab).

Candidate pairs are triangles whose bounding spheres overlap (one KD-tree query);
a vectorised plane-separation test drops the pairs where one triangle lies strictly on
one side of the other's plane, and the few left are confirmed exactly with
:func:`spacemesh.data.validate.triangles_intersect`. As in
:func:`spacemesh.metrics.quality.self_intersecting_faces`, pairs that share corners are
shrunk slightly first, so that a shared edge or corner does not count, and triangles of
the same polygon face are never compared.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.data.validate import triangles_intersect, triangles_of
from spacemesh.mesh import PolygonMesh
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Shrink of triangles that share corners, as a fraction of their size (large enough
#: that rounding in nearly coplanar neighbours never reads as a crossing).
SHRINK = 1e-3
#: Two triangles on one edge are compared only when folded onto each other: their
#: normals' dot product is below minus this.
FOLDED_COSINE = 0.999


def _shrunk(corners: FloatArray, factor: float) -> FloatArray:
    centre = corners.mean(axis=-2, keepdims=True)
    return centre + (corners - centre) * (1.0 - factor)


def _separated(ta: FloatArray, tb: FloatArray, eps: float) -> BoolArray:
    """``(M,)`` pairs where one triangle lies strictly on one side of the other's plane."""
    out = np.zeros(len(ta), dtype=bool)
    for s, t in ((ta, tb), (tb, ta)):
        normal = np.cross(s[:, 1] - s[:, 0], s[:, 2] - s[:, 0])  # (M, 3)
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = normal / np.where(length > 0, length, 1.0)
        side = np.einsum("mkd,md->mk", t - s[:, None, 0], normal)  # (M, 3)
        out |= np.all(side > eps, axis=1) | np.all(side < -eps, axis=1)
        out |= length[:, 0] == 0  # a degenerate triangle intersects nothing
    return out


def intersecting_triangles(vertices: FloatArray, triangles: IntArray,
                           source_face: IntArray | None = None) -> BoolArray:
    """Which triangles intersect another triangle (not of the same face).

    Parameters
    ----------
    vertices : (V, 3) float
    triangles : (T, 3) int
    source_face : (T,) int, optional
        The polygon face of each triangle (triangles of one face are not compared).

    Returns
    -------
    (T,) bool
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    hit = np.zeros(len(triangles), dtype=bool)
    if len(triangles) < 2:
        return hit
    corners = vertices[triangles]  # (T, 3, 3)
    centre = corners.mean(axis=1)
    radius = np.linalg.norm(corners - centre[:, None], axis=2).max(axis=1)  # (T,)
    extent = float(np.ptp(vertices[triangles.reshape(-1)], axis=0).max()) or 1.0
    eps = 1e-9 * extent
    pairs = cKDTree(centre).query_pairs(2 * float(radius.max()) + eps, output_type="ndarray")
    if len(pairs) == 0:
        return hit
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(centre[i] - centre[j], axis=1) <= radius[i] + radius[j] + eps
    if source_face is not None:
        near &= source_face[i] != source_face[j]
    i, j = i[near], j[near]
    common = (triangles[i][:, :, None] == triangles[j][:, None, :]).sum(axis=(1, 2))
    # triangles on one edge meet elsewhere only when folded flat onto each other
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    folded = np.einsum("md,md->m", normal[i], normal[j]) < -FOLDED_COSINE
    keep = (common < 2) | folded
    i, j, common = i[keep], j[keep], common[keep]
    shared = common > 0
    ta, tb = corners[i], corners[j]
    ta = np.where(shared[:, None, None], _shrunk(ta, SHRINK), ta)
    tb = np.where(shared[:, None, None], _shrunk(tb, SHRINK), tb)
    maybe = np.flatnonzero(~_separated(ta, tb, eps))
    for k in maybe.tolist():
        if hit[i[k]] and hit[j[k]]:
            continue
        if triangles_intersect(ta[k], tb[k], eps):
            hit[i[k]] = hit[j[k]] = True
    return hit


def self_intersecting_faces(mesh: PolygonMesh) -> BoolArray:
    """Which polygon faces of ``mesh`` intersect another face.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    (F,) bool
    """
    faces = np.zeros(mesh.n_faces, dtype=bool)
    if mesh.n_faces < 2:
        return faces
    triangles, source = triangles_of(mesh)
    hit = intersecting_triangles(mesh.vertices, triangles, source)
    faces[source[hit]] = True
    return faces
