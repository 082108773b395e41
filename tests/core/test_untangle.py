"""Untangling: crossing faces smoothed apart, connectivity and far vertices unchanged."""

from __future__ import annotations

import numpy as np

from spacemesh.examples import icosphere
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.geometry.untangle import untangle
from spacemesh.topology import check_topology


def test_a_vertex_pushed_through_the_far_side_is_smoothed_back():
    sphere = icosphere(2)
    vertices = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    top = int(np.argmax(vertices[:, 2]))
    pushed = vertices.copy()
    pushed[top] = [0.0, 0.0, -1.4]  # through the sphere and out of its bottom
    tangled = sphere.with_vertices(pushed)
    assert self_intersecting_faces(tangled).any()
    clean, stats = untangle(tangled)
    assert not self_intersecting_faces(clean).any()
    assert stats["crossing_before"] > 0 and stats["crossing_after"] == 0.0
    assert 1 <= stats["untangle_rounds"] <= 30
    assert clean.face_key_set() == tangled.face_key_set()
    assert check_topology(clean).is_closed_oriented_manifold
    # vertices far from the crossing stay where they were
    far = np.linalg.norm(vertices - [0.0, 0.0, 1.0], axis=1) > 1.2
    far &= np.linalg.norm(vertices - [0.0, 0.0, -1.0], axis=1) > 1.2
    assert far.any() and np.array_equal(clean.vertices[far], tangled.vertices[far])


def test_a_clean_mesh_is_returned_as_it_is():
    sphere = icosphere(2)
    clean, stats = untangle(sphere)
    assert clean is sphere and stats == {"untangle_rounds": 0, "crossing_before": 0.0,
                                         "crossing_after": 0.0}


def folded_lens(seed: int):
    """A thin lens (a flattened icosphere) with a patch folded through its other side."""
    rng = np.random.default_rng(seed)
    sphere = icosphere(2)
    vertices = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    vertices = vertices * [1.0, 1.0, 0.15]
    centre = rng.integers(len(vertices))
    patch = np.linalg.norm(vertices - vertices[centre], axis=1) < rng.uniform(0.2, 0.5)
    folded = vertices.copy()
    folded[patch, 2] = -vertices[patch, 2] * rng.uniform(1.2, 2.5)
    return sphere.with_vertices(folded)


def test_crossing_sheets_that_smoothing_leaves_are_pushed_apart_along_their_normals():
    tangled = folded_lens(37)
    assert self_intersecting_faces(tangled).any()
    # no smoothing round: the pushes alone part the fold
    clean, stats = untangle(tangled, max_rounds=0)
    assert not self_intersecting_faces(clean).any()
    assert stats["crossing_before"] > 0 and stats["crossing_after"] == 0.0
    assert stats["untangle_pushes"] != 0
    assert clean.face_key_set() == tangled.face_key_set()
    assert check_topology(clean).is_closed_oriented_manifold
    moved = np.any(clean.vertices != tangled.vertices, axis=1)
    assert moved.any() and moved.sum() < 0.5 * len(moved)  # only around the fold
    # with smoothing (the default) the same fold is mended by smoothing alone
    smoothed, smoothed_stats = untangle(tangled)
    assert not self_intersecting_faces(smoothed).any()
    assert "untangle_pushes" not in smoothed_stats


def test_vertex_normals_are_area_weighted_and_outward():
    from spacemesh.examples import cube_quads
    from spacemesh.mesh import PolygonMesh

    sphere = icosphere(3)
    radial = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    assert np.einsum("vd,vd->v", sphere.vertex_normals(), radial).min() > 0.99
    cube = cube_quads()  # a corner touches three equal squares: the diagonal
    corner = cube.vertex_normals()
    assert np.allclose(np.abs(corner), 1 / np.sqrt(3))
    assert np.all(np.sign(corner) == np.sign(cube.vertices - cube.vertices.mean(axis=0)))
    lone = PolygonMesh(np.vstack([cube.vertices, [[5.0, 5.0, 5.0]]]), cube.face_indices,
                       cube.face_offsets)  # a vertex without faces: no normal
    assert np.array_equal(lone.vertex_normals()[-1], np.zeros(3))


def test_crossing_faces_tracked_as_vertices_move_match_the_full_test():
    from spacemesh.examples import torus_grid
    from spacemesh.geometry.intersections import CrossingFaces

    rng = np.random.default_rng(3)
    for mesh in (icosphere(3), torus_grid(16, 10), folded_lens(37)):
        tracker = CrossingFaces(mesh)
        assert np.array_equal(tracker.faces(), self_intersecting_faces(mesh))
        positions = mesh.vertices.astype(np.float64).copy()
        spread = float(np.ptp(positions, axis=0).max())
        seen = 0
        for _ in range(12):  # a few vertices jump at a time, sometimes through the rest
            chosen = rng.choice(len(positions), size=rng.integers(1, 6), replace=False)
            positions[chosen] += rng.normal(scale=0.3 * spread, size=(len(chosen), 3))
            expected = self_intersecting_faces(mesh.with_vertices(positions))
            assert np.array_equal(tracker.move(positions), expected)
            seen += int(expected.any())
        assert seen > 0  # the moves made crossings to track
