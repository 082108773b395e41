"""What an automatic region finds: the holes (boundary loops) and the defects
(non-manifold or misoriented edges, pinched vertices, degenerate faces) of a mesh, each
a :class:`Finding` (:func:`find_issues`), and the faces around them (:func:`auto_faces`).

numpy and scipy only; nothing here changes the mesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels, faces_touching
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.typed import BoolArray, IntArray

#: Findings and regions listed in a report (the counts are always complete).
MAX_REPORTED = 20
#: Defect kinds an ``auto`` region finds besides holes.
DEFECT_KINDS = ("non-manifold-edges", "misoriented-edges", "pinched-vertices",
                "degenerate-faces")


@dataclass(frozen=True)
class Finding:
    """One hole or defect found.

    Attributes
    ----------
    kind : str
        ``hole`` or one of :data:`DEFECT_KINDS`.
    size : int
        Vertices of the loop (holes) or the defect's vertices.
    vertices : (K,) int64
        Its vertices (in the working mesh).
    """

    kind: str
    size: int
    vertices: IntArray

    def ring(self, mesh: PolygonMesh) -> BoolArray:
        """(F,) the faces of ``mesh`` touching its vertices."""
        marked = np.zeros(mesh.n_vertices, dtype=bool)
        marked[self.vertices] = True
        return faces_touching(mesh, marked)


def _clusters(mesh: PolygonMesh, edges: IntArray, marked: BoolArray) -> list[IntArray]:
    """Marked vertices grouped by the ``edges`` joining them."""
    n = mesh.n_vertices
    ids = np.flatnonzero(marked)
    if ids.size == 0:
        return []
    keep = marked[edges[:, 0]] & marked[edges[:, 1]] if len(edges) else np.zeros(0, bool)
    _, label = component_labels(n, edges[keep])  # (V,)
    order = ids[np.argsort(label[ids], kind="stable")]
    cuts = np.flatnonzero(np.diff(label[order])) + 1
    return [np.sort(group) for group in np.split(order, cuts)]


def find_issues(mesh: PolygonMesh, mode: str) -> list[Finding]:
    """The holes (``mode`` ``holes`` or ``all``) and defects (``defects`` or ``all``).

    A hole is a connected set of open edges (a boundary loop; loops touching at a
    vertex are one). A defect is a connected set of vertices of one kind. A vertex of a
    hole that also has a closed fan of faces (it stays pinched whatever fills the hole)
    is a ``pinched-vertices`` finding in every mode.
    """
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    he, count = sub.halfedges, sub.edge_count[sub.edge]
    n = mesh.n_vertices
    found: list[Finding] = []
    fans = sub.fan_counts(n)
    open_fans = np.bincount(he[count == 1][:, 0], minlength=n)
    if mode in ("holes", "all"):
        open_he = he[count == 1]
        marked = np.zeros(n, dtype=bool)
        marked[open_he.reshape(-1)] = True
        found += [Finding("hole", len(g), g) for g in _clusters(mesh, open_he, marked)]
    if mode == "holes":
        stuck = (open_fans > 0) & (fans > open_fans)
        found += [Finding("pinched-vertices", len(g), g)
                  for g in _clusters(mesh, mesh.edges, stuck)]
    if mode in ("defects", "all"):
        marks = {k: np.zeros(n, dtype=bool) for k in DEFECT_KINDS}
        marks["non-manifold-edges"][he[count > 2].reshape(-1)] = True
        marks["misoriented-edges"][he[(count == 2) & (sub.twin < 0)].reshape(-1)] = True
        marks["pinched-vertices"][fans > 1] = True
        nn = max(n, 1)
        fv = np.sort(sub.face * nn + he[:, 0])
        repeated = np.unique(fv[1:][fv[1:] == fv[:-1]] // nn)
        degenerate = np.zeros(mesh.n_faces, dtype=bool)
        degenerate[repeated] = True
        degenerate |= mesh.face_sizes < 3
        marks["degenerate-faces"][mesh.face_indices[degenerate[mesh.face_of_corner]]] = True
        # a vertex pinched only by loops touching there (all its fans open) is part
        # of a hole; one with a closed fan besides stays pinched whatever fills the hole
        marks["pinched-vertices"] &= ~((open_fans > 0) & (open_fans == fans))
        edges = mesh.edges
        for kind in DEFECT_KINDS:
            found += [Finding(kind, len(g), g) for g in _clusters(mesh, edges, marks[kind])]
    return found


def auto_faces(mesh: PolygonMesh, mode: str) -> BoolArray:
    """(F,) faces an ``{"auto": mode}`` region selects in ``mesh`` (as it is, before any
    orientation): the faces around every finding of :func:`find_issues`."""
    mask = np.zeros(mesh.n_faces, dtype=bool)
    for finding in find_issues(mesh, mode):
        mask |= finding.ring(mesh)
    return mask
