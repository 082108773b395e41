"""Restricted Delaunay meshes of farthest points: the ``farthest`` style's connectivity."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.data.voronoi import restricted_delaunay, voronoi_labels
from spacemesh.examples import icosphere
from spacemesh.geometry import farthest_point_sampling
from spacemesh.primitives import sample_surface, signed_volume, triangles_of
from spacemesh.topology import check_topology


def unit_sphere(level: int):
    sphere = icosphere(level)
    return sphere.with_vertices(sphere.vertices / np.linalg.norm(sphere.vertices, axis=1,
                                                                 keepdims=True))


def test_labels_are_the_nearest_seed_along_the_edges():
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [1.5, 1, 0]])
    triangles = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4]])
    labels = voronoi_labels(vertices, triangles, np.array([0, 3]))
    assert labels.tolist()[:4] == [0, 0, 1, 1]


@pytest.mark.parametrize("count", [40, 150])
def test_farthest_points_of_a_sphere_make_a_closed_outward_sphere(count):
    dense = unit_sphere(5)
    points, _ = sample_surface(dense, 2048, np.random.default_rng(count))
    sites = points[farthest_point_sampling(points, count)]
    mesh = restricted_delaunay(dense, sites)
    topology = check_topology(mesh)
    assert topology.is_closed_oriented_manifold and topology.genus == 0
    assert mesh.n_vertices == count and mesh.n_faces == 2 * count - 4
    # the vertices are the sites themselves, and the mesh encloses most of the ball
    assert np.allclose(np.sort(mesh.vertices, axis=0), np.sort(sites, axis=0))
    assert 0.8 * 4 / 3 * np.pi < signed_volume(mesh) < 4 / 3 * np.pi


def test_a_torus_keeps_its_handle():
    import manifold3d

    from spacemesh.data.shapes import solid_to_mesh

    torus = solid_to_mesh(manifold3d.Manifold.revolve(
        manifold3d.CrossSection.circle(0.3, 48).translate((1.0, 0.0)), 96))
    dense = torus
    points, _ = sample_surface(dense, 4096, np.random.default_rng(1))
    mesh = restricted_delaunay(dense, points[farthest_point_sampling(points, 200)])
    topology = check_topology(mesh)
    assert topology.is_closed_oriented_manifold and topology.genus == 1
    assert len(triangles_of(mesh)[0]) == 2 * 200  # V - E + F = 0 for a torus
