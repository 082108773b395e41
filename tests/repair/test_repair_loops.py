"""The loops of a patch's border (:func:`spacemesh.repair.fill.loops.patch_loops`),
pinched borders included."""

from __future__ import annotations

import numpy as np

from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset
from spacemesh.repair.fill.flat import flat_surface
from spacemesh.repair.fill.loops import patch_loops
from spacemesh.topology import check_topology


def _rotations(cycle: list[int]) -> list[list[int]]:
    return [cycle[i:] + cycle[:i] for i in range(len(cycle))]


def _patch_of_two_fans(mesh: PolygonMesh, vertex: int) -> tuple[np.ndarray, list[list[int]]]:
    """Two faces around ``vertex`` that share no edge (a bow tie at ``vertex``) and the
    faces' own corner cycles."""
    around = [f for f in range(mesh.n_faces) if vertex in mesh.faces[f].tolist()]
    for i, first in enumerate(around):
        for second in around[i + 1:]:
            if len(set(mesh.faces[first].tolist()) & set(mesh.faces[second].tolist())) == 1:
                patch = np.zeros(mesh.n_faces, dtype=bool)
                patch[[first, second]] = True
                return patch, [mesh.faces[first].tolist(), mesh.faces[second].tolist()]
    raise AssertionError("no bow tie around the vertex")


def test_a_border_that_visits_a_vertex_twice_splits_into_one_loop_per_gap():
    mesh = icosphere(2)
    patch, cycles = _patch_of_two_fans(mesh, 0)
    loops = patch_loops(mesh, patch)
    assert loops is not None and len(loops) == 2  # not None: the border is pinched at 0
    found = [loop.tolist() for loop in loops]
    for cycle in cycles:  # each loop runs as its face did (the patch's direction)
        assert sum(loop in _rotations(cycle) for loop in found) == 1
    # filling every loop joins the fans at the pinched vertex into one disc again
    triangles = flat_surface(mesh.vertices, loops)
    kept = faces_subset(mesh, ~patch)
    filled = PolygonMesh(mesh.vertices,
                         np.concatenate([kept.face_indices, triangles.reshape(-1)]),
                         np.concatenate([kept.face_offsets, kept.face_offsets[-1]
                                         + 3 * np.arange(1, len(triangles) + 1)]))
    assert check_topology(filled).is_closed_oriented_manifold


def test_a_simple_border_is_one_loop_in_the_patch_direction():
    mesh = icosphere(2)
    faces = [f for f in range(mesh.n_faces) if 0 in mesh.faces[f].tolist()]
    patch = np.zeros(mesh.n_faces, dtype=bool)
    patch[faces] = True  # the fan of vertex 0: its border is its link
    [loop] = patch_loops(mesh, patch)
    assert 0 not in loop.tolist() and len(loop) == len(faces)
    he = {tuple(h) for h in mesh.halfedges[patch[mesh.face_of_corner]].tolist()}
    assert all((a, b) in he for a, b in zip(loop.tolist(), np.roll(loop, -1).tolist(), strict=True))
