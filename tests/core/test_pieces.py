"""The points' own piece count; fragments (tiny pieces beside a larger one) leave the
output; separate parts stay."""

from __future__ import annotations

import numpy as np

from spacemesh.examples import icosphere
from spacemesh.geometry.pieces import FragmentPolicy, drop_fragments, point_pieces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface
from spacemesh.topology import surface_topology
from tests.validity import assert_valid_mesh

TETRA = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])


def with_tetrahedra(offsets: list[np.ndarray], size: float = 0.05) -> PolygonMesh:
    """A unit icosphere and one small outward tetrahedron at each offset."""
    sphere = icosphere(2)
    vertices = [sphere.vertices]
    faces = [f for f in sphere.faces]
    start = sphere.n_vertices
    for offset in offsets:
        vertices.append(offset + size * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]))
        faces += list(TETRA + start)
        start += 4
    return PolygonMesh.from_faces(np.concatenate(vertices), faces)


def test_a_fragment_beside_the_surface_goes_and_a_part_away_from_it_stays():
    near, far = np.array([0.0, 0.0, 1.02]), np.array([3.0, 0.0, 0.0])
    mesh = with_tetrahedra([near, far])
    assert surface_topology(mesh).pieces == 3
    kept, dropped = drop_fragments(mesh)
    assert dropped == 1
    assert_valid_mesh(kept)
    assert surface_topology(kept).pieces == 2
    assert kept.n_vertices == mesh.n_vertices - 4
    assert np.isclose(kept.vertices[:, 0].max(), 3.05)  # the far part is still there


def test_a_two_face_pillow_goes_wherever_it_lies():
    far = with_tetrahedra([np.array([3.0, 0.0, 0.0])])  # a part away from the sphere stays
    start = far.n_vertices
    corners = np.array([[0.0, 3.0, 0.0], [0.1, 3.0, 0.0], [0.0, 3.1, 0.0]])
    mesh = PolygonMesh.from_faces(  # and a pillow as far away: two faces, one each way
        np.concatenate([far.vertices, corners]),
        [*far.faces, np.array([0, 1, 2]) + start, np.array([0, 2, 1]) + start])
    assert surface_topology(mesh).pieces == 3
    kept, dropped = drop_fragments(mesh)
    assert dropped == 1
    assert_valid_mesh(kept)
    assert kept.n_vertices == far.n_vertices and kept.n_faces == far.n_faces


def test_nothing_goes_from_a_mesh_of_one_piece_or_of_fragments_only():
    sphere = icosphere(2)
    assert drop_fragments(sphere) == (sphere, 0)
    two = with_tetrahedra([np.zeros(3)])
    lone, _ = PolygonMesh.from_faces(two.vertices, two.faces[-4:]).remove_unreferenced_vertices()
    pair = PolygonMesh.from_faces(
        np.concatenate([lone.vertices, lone.vertices + 0.01]),
        list(lone.faces) + [f + lone.n_vertices for f in lone.faces])
    assert drop_fragments(pair)[1] == 0


def test_the_policy_decides_what_is_small_and_what_is_near():
    mesh = with_tetrahedra([np.array([0.0, 0.0, 1.02])])
    assert drop_fragments(mesh, FragmentPolicy(max_vertices=3))[1] == 0
    assert drop_fragments(mesh, FragmentPolicy(max_area_share=1e-6))[1] == 0
    assert drop_fragments(mesh, FragmentPolicy(max_gap_edges=0.0))[1] == 0
    assert drop_fragments(mesh, FragmentPolicy())[1] == 1


def test_the_points_pieces_are_their_separate_groups_outliers_aside():
    rng = np.random.default_rng(4)
    sphere, _ = sample_surface(icosphere(3), 2048, rng)
    assert point_pieces(sphere) == 1
    noisy = sphere + rng.normal(scale=0.01, size=sphere.shape)
    assert point_pieces(noisy) == 1
    apart = np.concatenate([sphere, sphere + np.array([3.0, 0.0, 0.0])])
    assert point_pieces(apart) == 2
    touching = np.concatenate([sphere, sphere + np.array([2.01, 0.0, 0.0])])  # a gap of 0.01
    assert point_pieces(touching) == 1
    stray = np.concatenate([sphere, rng.uniform(4, 9, size=(10, 3))])  # 0.5% outliers
    assert point_pieces(stray) == 1
    assert point_pieces(sphere[:1]) == 0
