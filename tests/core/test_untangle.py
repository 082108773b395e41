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
