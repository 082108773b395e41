"""The halfedge mesh type and its validity checks (paper Sec. 3.1).

A halfedge mesh is a pair of permutations ``twin`` and ``next`` over halfedges, plus
each halfedge's origin vertex. It is valid when twin is a fixed-point-free involution,
``next`` is a permutation without fixed points, ``next`` starts where its predecessor
ends, every orbit of ``next`` (a face) has at least three sides and no repeated vertex,
and the halfedges leaving each vertex form a single cycle under ``next o twin`` (one fan,
so the mesh is vertex-manifold). Such a mesh is oriented and edge-manifold by
construction: each edge has exactly two opposite halfedges in two faces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from spacemesh.connectivity import Connectivity
from spacemesh.typed import IntArray


@dataclass(frozen=True)
class HalfedgeMesh:
    """Halfedge connectivity.

    Parameters
    ----------
    origin : (H,) int64
        Vertex each halfedge leaves.
    twin : (H,) int64
    next : (H,) int64
    n_vertices : int
    """

    origin: IntArray
    twin: IntArray
    next: IntArray
    n_vertices: int

    @classmethod
    def from_connectivity(cls, connectivity: Connectivity) -> HalfedgeMesh:
        """The halfedge mesh of a SpaceMesh :class:`Connectivity`."""
        return cls(
            connectivity.origin, connectivity.twin, connectivity.next, connectivity.n_vertices
        )

    @property
    def n_halfedges(self) -> int:
        """Number of halfedges ``H``."""
        return len(self.origin)

    def _cycle_labels(self, perm: IntArray) -> IntArray:
        h = self.n_halfedges
        graph = coo_matrix((np.ones(h), (np.arange(h), perm)), shape=(h, h))
        return connected_components(graph, directed=True, connection="strong")[1]

    def face_labels(self) -> IntArray:
        """(H,) the face (orbit of ``next``) of each halfedge."""
        return self._cycle_labels(self.next)

    def problems(self) -> list[str]:
        """Every violated validity condition, as text (empty when valid)."""
        h = self.n_halfedges
        out: list[str] = []
        if h == 0:
            return out
        ids = np.arange(h)
        twin, nxt, origin = self.twin, self.next, self.origin
        for name, perm in (("twin", twin), ("next", nxt)):
            if perm.min() < 0 or perm.max() >= h:
                return [f"{name} refers to halfedges that do not exist"]
            if len(np.unique(perm)) != h:
                return [f"{name} is not a permutation"]
            if np.any(perm == ids):
                out.append(f"{name} has fixed points")
        if np.any(twin[twin] != ids):
            out.append("twin is not an involution")
        target = origin[twin]
        if np.any(origin[nxt] != target):
            out.append("next does not start where its halfedge ends")
        if np.any(origin == target):
            out.append("a halfedge is a loop")
        if out:
            return out
        face = self.face_labels()
        sizes = np.bincount(face)
        if np.any(sizes < 3):
            out.append(f"{int(np.sum(sizes < 3))} faces have fewer than 3 sides")
        key = np.sort(face.astype(np.int64) * self.n_vertices + origin)
        if np.any(key[1:] == key[:-1]):
            out.append("a face visits a vertex twice")
        # one fan per vertex: next o twin cycles the halfedges leaving each vertex
        rotation = nxt[twin]
        fans = self._cycle_labels(rotation)
        fan_count = np.bincount(np.unique(np.stack([origin, fans], 1), axis=0)[:, 0])
        if np.any(fan_count > 1):
            out.append(f"{int(np.sum(fan_count > 1))} vertices have more than one fan")
        pairs = np.sort(np.stack([origin, target], 1), axis=1)
        if len(np.unique(pairs, axis=0)) * 2 != h:
            out.append("an edge has more than two halfedges")
        return out

    def is_valid(self) -> bool:
        """True when :meth:`problems` finds nothing."""
        return not self.problems()
