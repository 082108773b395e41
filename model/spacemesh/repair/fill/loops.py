"""A hole's patch read as faces of a mesh: the loops of its border, the parts it falls
into, the density of the surface around it and its Euler characteristic.

numpy and scipy only; nothing here changes a mesh.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import edge_keys, faces_subset, faces_touching, vertices_of
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.repair.pinched import split_pinched
from spacemesh.topology import check_topology, vertex_connected_faces
from spacemesh.typed import BoolArray, IntArray


def patch_loops(mesh: PolygonMesh, patch: BoolArray) -> list[IntArray] | None:
    """The loops of the patch's border (its edges with no patch face on the other side),
    in the patch's direction, or None when they cannot be made simple cycles.

    A border that visits a vertex twice (a hole whose loops touch at a vertex, pinched)
    is split there as the hole's own loops are (:func:`spacemesh.repair.pinched.
    split_pinched`: each gap between the kept fans at that vertex is one corner of one
    loop), so that filling every loop again joins the fans into one disc."""
    inside = patch[mesh.face_of_corner]
    he = mesh.halfedges[inside]
    n = max(mesh.n_vertices, 1)
    key = he[:, 0] * n + he[:, 1]
    border = he[~np.isin(he[:, 1] * n + he[:, 0], key)]
    if len(np.unique(border[:, 0])) != len(border):
        return _pinched_patch_loops(mesh, patch, border)
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


def _pinched_patch_loops(mesh: PolygonMesh, patch: BoolArray, border: IntArray
                         ) -> list[IntArray] | None:
    """The simple loops of a patch ``border`` ((B, 2) halfedges in the patch's
    direction) that visits a vertex twice: the kept faces' open halfedges opposite it,
    split at the vertices they pass twice (:func:`spacemesh.repair.pinched.
    split_pinched`), or None where they cannot be split."""
    kept = faces_subset(mesh, ~patch)  # the same vertex indices
    sub = FaceSubset.of(kept, np.arange(kept.n_faces))
    open_ids = np.flatnonzero(sub.edge_count[sub.edge] == 1)
    n = max(mesh.n_vertices, 1)
    he = sub.halfedges[open_ids]  # (O, 2) each the reverse of a border halfedge or not
    opposite = np.isin(he[:, 1] * n + he[:, 0], border[:, 0] * n + border[:, 1])
    return split_pinched(kept, sub, open_ids[opposite])


def patch_parts(mesh: PolygonMesh, patch: BoolArray) -> list[BoolArray]:
    """The parts of a region's patch ((F,) bool) that share no vertex: one per hole, or
    per group of holes whose loops touch."""
    n_parts, part = vertex_connected_faces(mesh, patch)  # part (F,), -1 outside
    return [part == k for k in range(n_parts)]


def boundary_edge_length(mesh: PolygonMesh, loops: list[IntArray]) -> float:
    """Mean length of the edges of the closed ``loops`` (vertex cycles)."""
    lengths = [np.linalg.norm(mesh.vertices[loop] - mesh.vertices[np.roll(loop, -1)], axis=1)
               for loop in loops if len(loop) > 1]
    return float(np.concatenate(lengths).mean()) if lengths else 0.0


def patch_edge_length(mesh: PolygonMesh, patch: BoolArray) -> float:
    """Mean length of the edges on the patch's border (one side in the patch, the other
    outside it): the density of the surface around the patch (0 without such edges)."""
    # every side of an edge at a patch vertex is a side of a face touching one: the
    # counts below are the whole mesh's for the patch's edges, in the same order
    around = faces_touching(mesh, vertices_of(mesh, patch))
    near = faces_subset(mesh, around)
    he = near.halfedges
    inside = patch[around][near.face_of_corner]
    key = edge_keys(he, mesh.n_vertices)
    _, edge, count = np.unique(key, return_inverse=True, return_counts=True)
    sides = np.bincount(edge, inside, minlength=len(count))
    border = (count[edge] == 2) & inside & (sides[edge] == 1)
    if not border.any():
        return 0.0
    p = mesh.vertices
    return float(np.linalg.norm(p[he[border, 0]] - p[he[border, 1]], axis=1).mean())


def patch_euler(mesh: PolygonMesh, patch: BoolArray) -> int:
    """The Euler characteristic V - E + F of the ``patch`` faces ((F,) bool) with their
    own vertices and edges (1 for a disc, 0 for a tube, -1 for a disc with a handle)."""
    return check_topology(faces_subset(mesh, patch)).euler_characteristic
