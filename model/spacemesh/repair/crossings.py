"""Whether a repair's new faces cross the mesh: the check that makes the repair sample a
region again (:data:`spacemesh.repair.api.TOPOLOGY_ATTEMPTS`; docs/REPAIR.md, "Limits")."""

from __future__ import annotations

import numpy as np

from spacemesh.geometry.intersections import crossing_pairs
from spacemesh.primitives import faces_subset, triangles_of
from spacemesh.repair.splice import Spliced


def new_crossings(spliced: Spliced) -> int:
    """How many of a spliced mesh's new faces cross a face (new or kept), by the exact
    test (:func:`spacemesh.geometry.intersections.crossing_pairs` from the new faces'
    triangles, among the faces whose bounding boxes meet the new faces' box: its cost
    grows with the patch, not the mesh)."""
    mesh = spliced.mesh
    new = spliced.face_source < 0  # (F,)
    if not new.any():
        return 0
    corners = mesh.vertices[mesh.face_indices]  # (C, 3)
    starts = mesh.face_offsets[:-1]
    low = np.minimum.reduceat(corners, starts, axis=0)  # (F, 3) each face's box
    high = np.maximum.reduceat(corners, starts, axis=0)
    near = np.flatnonzero(np.all(high >= low[new].min(axis=0), axis=1)
                          & np.all(low <= high[new].max(axis=0), axis=1))  # (K,)
    local = np.zeros(mesh.n_faces, dtype=bool)
    local[near] = True
    triangles, source = triangles_of(faces_subset(mesh, local))  # source: into ``near``
    pairs = crossing_pairs(mesh.vertices, triangles, source,
                           among=np.flatnonzero(new[near][source]))  # (P, 2)
    faces = near[np.unique(source[pairs.reshape(-1)])]
    return int(new[faces].sum())


__all__ = ["new_crossings"]
