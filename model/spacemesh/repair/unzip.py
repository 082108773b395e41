"""Unzipping defects: the non-manifold edges and pinched vertices of a mesh split into
one vertex per fan of faces, every face kept (:func:`unzip_defects`), and the fins left
over at edges of more than two sides (:func:`unpaired_faces`). What was a fin or a second
sheet becomes a surface with an open boundary, which the hole filling closes.

numpy and scipy only.
"""

from __future__ import annotations

import itertools

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.typed import BoolArray, IntArray

#: Defect kinds :func:`unzip_defects` resolves by splitting vertices.
SPLIT_KINDS = ("non-manifold-edges", "pinched-vertices")


def _pair_sides(mesh: PolygonMesh, sub: FaceSubset) -> IntArray:
    """(S,) the twin of each halfedge, with the sides of edges of more than two sides
    paired too (:func:`unzip_defects`); -1 for a side left open."""
    he = sub.halfedges
    mate = sub.twin.copy()
    normals = mesh.face_normals()
    crowded = np.flatnonzero(sub.edge_count[sub.edge] > 2)
    order = crowded[np.argsort(sub.edge[crowded], kind="stable")]
    cuts = np.flatnonzero(np.diff(sub.edge[order])) + 1
    for group in np.split(order, cuts) if len(order) else []:
        pairs = [(float(normals[sub.face[a]] @ normals[sub.face[b]]), int(a), int(b))
                 for a, b in itertools.combinations(group.tolist(), 2)
                 if he[a, 0] == he[b, 1] and sub.face[a] != sub.face[b]]
        taken: set[int] = set()
        for _, a, b in sorted(pairs, reverse=True):
            if a not in taken and b not in taken:
                mate[a], mate[b] = b, a
                taken |= {a, b}
    return mate


def unpaired_faces(mesh: PolygonMesh) -> BoolArray:
    """(F,) the faces left over at edges of more than two sides (:func:`_pair_sides`:
    a fin whose fans :func:`unzip_defects` could not separate)."""
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    mate = _pair_sides(mesh, sub)
    left = (sub.edge_count[sub.edge] > 2) & (mate < 0)
    out = np.zeros(mesh.n_faces, dtype=bool)
    out[sub.face[left]] = True
    return out


def unzip_defects(mesh: PolygonMesh, vertices: BoolArray) -> PolygonMesh:
    """Split the non-manifold edges and pinched vertices among ``vertices`` ((V,) bool):
    every face keeps its corners' positions, but a vertex with several fans of faces gets
    one copy per fan.

    At an edge with more than two sides, the sides running opposite ways are paired,
    the pair of faces with the most aligned normals first (the sheet that continues
    flattest across the edge, so a fin standing on a surface is the side left over);
    a side left unpaired becomes an open edge. Fans are then joined across paired
    sides (as :meth:`FaceSubset.fan_counts` does across manifold edges), and every fan
    of a marked vertex but its first gets a new vertex at the same position, appended.
    What was a fin or a second sheet joined along an edge or at a vertex becomes a
    surface with an open boundary there, which the hole filling closes.

    Parameters
    ----------
    mesh : PolygonMesh
    vertices : (V,) bool
        The vertices that may be split (the defects' vertices).

    Returns
    -------
    PolygonMesh
        The same faces in the same order (same first corners, same positions), over
        ``mesh``'s vertices then the copies.
    """
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    he = sub.halfedges
    mate = _pair_sides(mesh, sub)
    total = len(he)
    has = np.flatnonzero(mate >= 0)
    _, fan = component_labels(total, np.stack([has, sub.next[mate[has]]], axis=1))  # (S,)
    origin = he[:, 0]
    split = vertices[origin]
    first_fan = np.full(mesh.n_vertices, -1, dtype=np.int64)
    ids = np.flatnonzero(split)[::-1]
    first_fan[origin[ids]] = fan[ids]  # the fan of each vertex's first corner
    extra = split & (fan != first_fan[origin])
    new_fans, which = np.unique(fan[extra], return_inverse=True)
    corners = mesh.face_indices.copy()  # halfedge i leaves corner i (all faces, in order)
    corners[extra] = mesh.n_vertices + which.reshape(-1)
    copy_of = np.zeros(len(new_fans), dtype=np.int64)
    copy_of[which.reshape(-1)] = origin[extra]
    vertices_out = np.concatenate([mesh.vertices, mesh.vertices[copy_of]])
    return PolygonMesh(vertices_out, corners, mesh.face_offsets)
