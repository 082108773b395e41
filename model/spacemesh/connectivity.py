"""Halfedge connectivity as SpaceMesh sees it: edges plus a cyclic order at each vertex.

This is the common intermediate of encoding (mesh -> ground truth) and decoding
(embeddings -> mesh). Neighbour lists are CSR, sorted by neighbour index. Slot ``s`` of
vertex ``i`` is the halfedge ``i -> neighbours[s]``; ``successor[s]`` is the slot ``t`` (of
the same vertex) such that ``next(n_s -> i) = (i -> n_t)``. Faces are the orbits of
``next``; a face's vertex cycle lists the origin of each of its halfedges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray, IntArray


@dataclass(frozen=True)
class Connectivity:
    """Edges and cyclic neighbour orders of ``n_vertices`` vertices.

    Parameters
    ----------
    n_vertices : int
    offsets : (N + 1,) int64
        CSR offsets; vertex ``i`` owns slots ``offsets[i]:offsets[i + 1]``.
    neighbours : (2E,) int64
        Neighbour of each slot, ascending within a vertex.
    successor : (2E,) int64
        Slot of the next outgoing halfedge, see the module docstring.
    """

    n_vertices: int
    offsets: IntArray
    neighbours: IntArray
    successor: IntArray

    @property
    def degree(self) -> IntArray:
        """(N,) number of neighbours of each vertex."""
        return np.diff(self.offsets)

    @property
    def origin(self) -> IntArray:
        """(H,) origin vertex of each halfedge (slot)."""
        return np.repeat(np.arange(self.n_vertices, dtype=np.int64), self.degree)

    @property
    def edges(self) -> IntArray:
        """(E, 2) undirected edges ``i < j``, sorted."""
        origin = self.origin
        keep = origin < self.neighbours
        return np.stack([origin[keep], self.neighbours[keep]], axis=1)

    @property
    def twin(self) -> IntArray:
        """(H,) the slot of the opposite halfedge ``j -> i`` for each slot ``i -> j``."""
        return twin_slots(self.offsets, self.neighbours)

    @property
    def next(self) -> IntArray:
        """(H,) halfedge ``next``: ``next(j -> i) = (i -> n_t)`` where ``t = successor[i -> j]``."""
        # the halfedge j -> i is twin(i -> j) = twin[s]; its next is successor[s].
        nxt = np.empty_like(self.successor)
        nxt[self.twin] = self.successor
        return nxt

    def next_triplets(self) -> IntArray:
        """(H, 3) rows ``(i, j, k)`` with ``next(j -> i) = (i -> k)``."""
        return np.stack([self.origin, self.neighbours, self.neighbours[self.successor]], axis=1)

    def local_successor(self) -> IntArray:
        """(H,) successor as a local index ``0 .. degree - 1`` within each vertex."""
        return self.successor - np.repeat(self.offsets[:-1], self.degree)

    def faces(self) -> tuple[IntArray, IntArray]:
        """The orbits of ``next`` as polygon faces.

        Returns
        -------
        face_indices : (H,) int64
            Vertex cycles of all faces, concatenated.
        face_offsets : (F + 1,) int64
        """
        nxt = self.next.tolist()
        origin = self.origin.tolist()
        visited = bytearray(len(nxt))
        indices: list[int] = []
        offsets = [0]
        for start in range(len(nxt)):
            if visited[start]:
                continue
            h = start
            while not visited[h]:
                visited[h] = 1
                indices.append(origin[h])
                h = nxt[h]
            offsets.append(len(indices))
        return np.asarray(indices, dtype=np.int64), np.asarray(offsets, dtype=np.int64)

    def to_mesh(self, vertices: FloatArray) -> PolygonMesh:
        """The polygon mesh whose faces are the orbits of ``next``."""
        indices, offsets = self.faces()
        return PolygonMesh(vertices, indices, offsets)


def csr_from_edges(edges: IntArray, n_vertices: int) -> tuple[IntArray, IntArray]:
    """Sorted CSR neighbour lists from undirected edges.

    Parameters
    ----------
    edges : (E, 2) int64
        Undirected edges (no duplicates, no loops).
    n_vertices : int

    Returns
    -------
    offsets : (N + 1,) int64
    neighbours : (2E,) int64
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    src = np.concatenate([edges[:, 0], edges[:, 1]])
    dst = np.concatenate([edges[:, 1], edges[:, 0]])
    order = np.lexsort((dst, src))
    counts = np.bincount(src, minlength=n_vertices)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return offsets, dst[order]


def slot_lookup(offsets: IntArray, neighbours: IntArray, i: IntArray, j: IntArray) -> IntArray:
    """Slot of halfedge ``i -> j`` for arrays of pairs (each must exist).

    Parameters
    ----------
    offsets, neighbours : CSR neighbour lists
    i, j : (M,) int64

    Returns
    -------
    (M,) int64
    """
    n = len(offsets) - 1
    keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(offsets)) * n + neighbours
    # keys are sorted because rows are in order and neighbours ascend within a row
    return np.searchsorted(keys, np.asarray(i) * n + np.asarray(j)).astype(np.int64)


def twin_slots(offsets: IntArray, neighbours: IntArray) -> IntArray:
    """(H,) for each slot ``i -> j`` the slot of ``j -> i``."""
    origin = np.repeat(np.arange(len(offsets) - 1, dtype=np.int64), np.diff(offsets))
    return slot_lookup(offsets, neighbours, neighbours, origin)
