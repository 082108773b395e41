"""Replacing the patch a region made by another fill of its loops: the faired fan
(:func:`fan_instead`), MeshFix's fill (:func:`meshfix_instead`), the least-area flat
fill (:func:`flat_instead`), or any triangles (:func:`fill_instead`); every other face
is kept.

numpy and scipy only (MeshFix's fill: the optional ``pymeshfix``).
"""

from __future__ import annotations

import numpy as np

from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset, faces_touching, vertices_of
from spacemesh.repair.fill.fan import faired_fan
from spacemesh.repair.fill.flat import flat_surface
from spacemesh.repair.fill.loops import patch_loops
from spacemesh.repair.fill.passes import Passes
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.typed import BoolArray, FloatArray, IntArray


def fan_instead(state: Passes, index: int, policy: FillPolicy,
                fan: tuple[PolygonMesh, IntArray, BoolArray] | None = None) -> bool:
    """Replace the faces the region ``index`` made by a fan over each of their loops,
    refined and faired (:func:`~spacemesh.repair.fill.fan.faired_fan`, or ``fan`` when
    given); True when it did: only when that patch is faired all the way (no
    self-intersection held it back) with a smooth fairing (not one of the ``policy``'s
    :attr:`~spacemesh.repair.fill.policy.FillPolicy.meshfix_fairings`)."""
    mesh = state.mesh
    patch = state.made_by == index
    if fan is None:
        fan = faired_fan(mesh, patch, policy)
    if fan is None:
        return False
    faired, face_source, _ = fan
    own = np.zeros(faired.n_vertices, dtype=bool)  # the region's old vertices, now unused
    own[: mesh.n_vertices] = (state.origin == index) & ~vertices_of(mesh, ~patch)
    ids = np.cumsum(~own) - 1
    out = PolygonMesh(faired.vertices[~own], ids[faired.face_indices], faired.face_offsets)
    vertex_map = np.where(own[: mesh.n_vertices], -1, ids[: mesh.n_vertices])
    state.apply(vertex_map.astype(np.int64), face_source.astype(np.int64), out, index)
    return True


def meshfix_instead(state: Passes, index: int, policy: FillPolicy,
                    patch: BoolArray | None = None) -> bool:
    """Replace the faces ``patch`` ((F,) bool; by default every face) the region
    ``index`` made by MeshFix's fill of their loops (the ``policy``'s,
    :func:`spacemesh.repair.fill.meshfix.meshfix_fill`); every other face is kept.
    True when it did (False without ``pymeshfix``, or when MeshFix's patch does not
    close exactly these loops)."""
    mesh = state.mesh
    if patch is None:
        patch = state.made_by == index
    loops = patch_loops(mesh, patch)
    if not loops or not patch.any():
        return False
    filled = policy.meshfix_fill(faces_subset(mesh, ~patch), loops)
    return filled is not None and fill_instead(state, index, patch, *filled) is not None


def flat_instead(state: Passes, index: int, part: BoolArray, policy: FillPolicy
                 ) -> IntArray | None:
    """Replace the patch faces ``part`` ((F,) bool: one hole's) by the least-area flat
    triangulation of their loops (:func:`spacemesh.repair.fill.flat.flat_surface`, no new
    vertex), where the probes prefer that fill and the patch could not be laid onto it
    (:func:`spacemesh.repair.fill.finish.onto_flat`), when that adds no
    self-intersection near the hole: the face each new face is (:func:`fill_instead`),
    or None when it did not."""
    loops = patch_loops(state.mesh, part)
    triangles = (flat_surface(state.mesh.vertices, loops, policy.max_flat_loop)
                 if loops else None)
    if triangles is None:
        return None
    return fill_instead(state, index, part, np.zeros((0, 3)), triangles, guard=True)


def repeated_halfedges(mesh: PolygonMesh) -> int:
    """How many halfedges of ``mesh`` repeat another's direction between the same two
    vertices (0 on an oriented manifold mesh)."""
    he = mesh.halfedges
    key = he[:, 0] * max(mesh.n_vertices, 1) + he[:, 1]
    return len(key) - len(np.unique(key))


def fill_instead(state: Passes, index: int, patch: BoolArray, points: FloatArray,
                 triangles: IntArray, *, guard: bool = False) -> IntArray | None:
    """Replace the faces ``patch`` ((F,) bool) the region ``index`` made by the
    ``triangles`` (T, 3) over the current mesh's vertices then the new ``points``
    (P, 3); every other face is kept. Returns the face of the mesh before each face of
    the new one is ((F',) int64, -1 for the new faces), or None when it did not
    replace them: when a triangle uses a vertex that goes with the patch, when a new
    face repeats an edge the mesh has (:func:`repeated_halfedges`), or, with
    ``guard``, when the new faces add a self-intersection near the hole."""
    mesh = state.mesh
    # the vertices the region made that no kept face uses go with these faces
    own = (state.origin == index) & ~vertices_of(mesh, ~patch)
    vertex_map = np.full(mesh.n_vertices, -1, dtype=np.int64)
    vertex_map[~own] = np.arange(int((~own).sum()))
    ids = np.concatenate([vertex_map, int((~own).sum()) + np.arange(len(points))])
    if (ids[triangles] < 0).any():
        return None
    kept = faces_subset(mesh, ~patch)
    indices = np.concatenate([vertex_map[kept.face_indices], ids[triangles].reshape(-1)])
    offsets = np.concatenate([kept.face_offsets, kept.face_offsets[-1]
                              + 3 * np.arange(1, len(triangles) + 1)]).astype(np.int64)
    out = PolygonMesh(np.concatenate([mesh.vertices[~own], points]), indices, offsets)
    source = np.concatenate([np.flatnonzero(~patch), np.full(len(triangles), -1)])
    if repeated_halfedges(out) > repeated_halfedges(mesh):
        return None  # a new face repeats an edge of the mesh (one between two loop vertices)
    if guard:
        def crossings(surface: PolygonMesh, faces: BoolArray) -> int:
            near = faces_touching(surface, vertices_of(surface, faces))
            return int(self_intersecting_faces(faces_subset(surface, near)).sum())

        if crossings(out, source < 0) > crossings(mesh, patch):
            return None
    state.apply(vertex_map, source.astype(np.int64), out, index)
    return source.astype(np.int64)
