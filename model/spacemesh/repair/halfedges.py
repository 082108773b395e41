"""The halfedge tables of a subset of a mesh's faces (:class:`FaceSubset`): how the
sides of its faces pair up into edges, and the fans of faces around each vertex. The
cut, the findings of an automatic region and the unzipping of defects all read them.

numpy and scipy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels, edge_keys
from spacemesh.typed import IntArray


@dataclass(frozen=True)
class FaceSubset:
    """The halfedges of a subset of a mesh's faces and how they pair up.

    Attributes
    ----------
    faces : (F',) int64
        Original indices of the faces in the subset.
    halfedges : (S, 2) int64
        ``(origin, target)`` of every face side, in face order.
    face : (S,) int64
        Original face of each halfedge.
    edge : (S,) int64
        Undirected edge id of each halfedge (0 .. E-1).
    edge_count : (E,) int64
        Face sides on each undirected edge.
    twin : (S,) int64
        The opposite halfedge when the edge has exactly two sides in opposite
        directions, else -1.
    next : (S,) int64
        Next halfedge in the same face.
    """

    faces: IntArray
    halfedges: IntArray
    face: IntArray
    edge: IntArray
    edge_count: IntArray
    twin: IntArray
    next: IntArray

    @classmethod
    def of(cls, mesh: PolygonMesh, faces: IntArray) -> FaceSubset:
        """Build the tables of ``mesh``'s faces ``faces``."""
        faces = np.asarray(faces, dtype=np.int64)
        sizes = mesh.face_sizes[faces]
        starts = mesh.face_offsets[faces]
        total = int(sizes.sum())
        first = np.repeat(np.cumsum(sizes) - sizes, sizes)
        local = np.arange(total, dtype=np.int64) - first
        corner = np.repeat(starts, sizes) + local
        size_rep = np.repeat(sizes, sizes)
        nxt = first + (local + 1) % np.maximum(size_rep, 1)
        origin = mesh.face_indices[corner]
        halfedges = np.stack([origin, origin[nxt]], axis=1) if total else np.zeros((0, 2), np.int64)
        key = edge_keys(halfedges, mesh.n_vertices)
        _, edge, count = np.unique(key, return_inverse=True, return_counts=True)
        edge = edge.reshape(-1).astype(np.int64)
        count = count.astype(np.int64)
        twin = np.full(total, -1, dtype=np.int64)
        pair = count[edge] == 2
        idx = np.flatnonzero(pair)
        if idx.size:
            order = idx[np.argsort(edge[idx], kind="stable")]
            a, b = order[0::2], order[1::2]
            opposite = halfedges[a, 0] == halfedges[b, 1]
            twin[a[opposite]] = b[opposite]
            twin[b[opposite]] = a[opposite]
        return cls(faces, halfedges, np.repeat(faces, sizes), edge, count, twin, nxt)

    def fan_counts(self, n_vertices: int) -> IntArray:
        """(V,) fans of faces around each vertex (0 when unused).

        An outgoing halfedge ``h`` and ``next(twin(h))`` leave the same vertex in two
        faces that share an edge; fans are the connected components of this relation.
        Only edges with a proper twin join faces (non-manifold edges split fans).
        """
        total = len(self.halfedges)
        if total == 0:
            return np.zeros(n_vertices, dtype=np.int64)
        has = np.flatnonzero(self.twin >= 0)
        rot = self.next[self.twin[has]]  # next(twin(h)) leaves the origin of h
        n_comp, label = component_labels(total, np.stack([has, rot], axis=1))  # label (S,)
        origin_of = np.zeros(n_comp, dtype=np.int64)
        origin_of[label] = self.halfedges[:, 0]
        return np.bincount(origin_of, minlength=n_vertices).astype(np.int64)
