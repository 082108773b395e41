"""The repair's fills read only the faces around a hole: the masks, the fairing's
solve, the border's edge length, the sharpest edge and the refinement give the same
numbers, bit for bit, whether or not the mesh has faces elsewhere (a mesh of 300,000
faces costs what the hole's neighbourhood costs, not what the mesh does)."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_touching, vertices_of
from spacemesh.repair.fill.fan import fan_fill
from spacemesh.repair.fill.laplace import fair_positions
from spacemesh.repair.fill.loops import patch_edge_length, patch_loops
from spacemesh.repair.fill.probe import _sharpest_edge, sharpest_edge
from spacemesh.repair.fill.refine import refine_patch
from tests.repair.auto_meshes import punched


def mixed_mesh() -> PolygonMesh:
    """Triangles, quads and a pentagon, with an unused vertex."""
    vertices = np.random.default_rng(0).normal(size=(12, 3))
    return PolygonMesh.from_faces(vertices, [[0, 1, 2], [2, 3, 4, 5], [5, 6, 7, 8, 9],
                                             [9, 10, 0], [1, 3, 6]])


@pytest.mark.parametrize("mesh", [icosphere(2), torus_grid(8, 6), mixed_mesh()],
                         ids=["triangles", "quads", "mixed"])
def test_masks_match_their_definitions(mesh):
    rng = np.random.default_rng(1)
    for share in (0.0, 0.05, 0.5, 1.0):
        vertices = rng.random(mesh.n_vertices) < share
        faces = rng.random(mesh.n_faces) < share
        touching = np.bincount(mesh.face_of_corner, vertices[mesh.face_indices],
                               minlength=mesh.n_faces) > 0
        corners = np.zeros(mesh.n_vertices, dtype=bool)
        corners[mesh.face_indices[faces[mesh.face_of_corner]]] = True
        np.testing.assert_array_equal(faces_touching(mesh, vertices), touching)
        np.testing.assert_array_equal(vertices_of(mesh, faces), corners)


def with_far_copy(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` followed by a copy of itself far away (its vertices after ``mesh``'s)."""
    return PolygonMesh.from_faces(np.vstack([mesh.vertices, mesh.vertices + 50.0]),
                                  mesh.faces + [f + mesh.n_vertices for f in mesh.faces])


def filled_hole() -> tuple[PolygonMesh, np.ndarray, np.ndarray]:
    """An icosphere with a hole closed by a fan: the mesh, its patch faces, its free
    vertices (the fan's centre)."""
    opened = punched(icosphere(3), [[0.0, 0.0, 1.0]], 0.45)
    loops = patch_loops(opened, np.ones(opened.n_faces, dtype=bool))
    assert loops is not None and len(loops) == 1
    filled, _ = fan_fill(opened, [loops[0][::-1]])
    patch = np.arange(filled.n_faces) >= opened.n_faces
    free = np.arange(filled.n_vertices) >= opened.n_vertices
    return filled, patch, free


def test_fills_read_only_the_faces_around_the_hole():
    mesh, patch, free = filled_hole()
    big = with_far_copy(mesh)
    pad_faces = np.zeros(big.n_faces - mesh.n_faces, dtype=bool)
    pad_vertices = np.zeros(big.n_vertices - mesh.n_vertices, dtype=bool)
    big_patch, big_free = np.concatenate([patch, pad_faces]), np.concatenate([free, pad_vertices])
    for order, weights in ((1, "uniform"), (2, "cotangent"), (3, "cotangent")):
        alone = fair_positions(mesh, free, order, weights)
        assert not np.array_equal(alone, mesh.vertices)  # the fan's centre moved
        np.testing.assert_array_equal(fair_positions(big, big_free, order, weights)
                                      [: mesh.n_vertices], alone)
    assert patch_edge_length(mesh, patch) > 0
    assert patch_edge_length(big, big_patch) == patch_edge_length(mesh, patch)
    ring = faces_touching(mesh, vertices_of(mesh, patch))
    assert sharpest_edge(mesh, ring) > 0
    assert sharpest_edge(big, np.concatenate([ring, pad_faces])) == sharpest_edge(mesh, ring)
    target = 0.5 * patch_edge_length(mesh, patch)
    refined, source = refine_patch(mesh, patch, target)
    big_refined, big_source = refine_patch(big, big_patch, target)
    assert refined.n_vertices > mesh.n_vertices  # the fan was split
    np.testing.assert_array_equal(big_refined.vertices[big.n_vertices:],
                                  refined.vertices[mesh.n_vertices:])
    new = np.stack([f for f, s in zip(refined.faces, source, strict=True) if s < 0])
    big_new = np.stack([f for f, s in zip(big_refined.faces, big_source, strict=True)
                        if s < 0])
    shift = big.n_vertices - mesh.n_vertices  # the new vertices follow the copy's
    np.testing.assert_array_equal(np.where(big_new >= big.n_vertices, big_new - shift,
                                           big_new), new)


def test_the_sharpest_edge_reads_the_whole_mesh_where_a_side_is_shared():
    mesh = icosphere(2)
    a, b, c = mesh.faces[0]
    twice = PolygonMesh.from_faces(mesh.vertices, [*mesh.faces, np.array([b, a, c])])
    faces = np.ones(twice.n_faces, dtype=bool)
    assert sharpest_edge(twice, faces) == _sharpest_edge(twice, faces)
    assert _sharpest_edge(twice, faces, unique_twins=True) is None  # the fallback ran
    assert sharpest_edge(mesh, np.ones(mesh.n_faces, dtype=bool)) == _sharpest_edge(
        mesh, np.ones(mesh.n_faces, dtype=bool))
