"""Validity flags, self-intersections, element-shape distributions."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere, prism, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics import (
    corner_angles,
    distribution_distance,
    edge_lengths,
    self_intersection_fraction,
    topology_flags,
)
from spacemesh.metrics.quality import self_intersecting_faces
from spacemesh.primitives import flip_faces

pytest.importorskip("pymeshlab")


def two_cubes(shift: float) -> PolygonMesh:
    cube = cube_quads(1.0)
    faces = [list(f) for f in cube.faces] + [list(f + 8) for f in cube.faces]
    return PolygonMesh.from_faces(np.vstack([cube.vertices, cube.vertices + shift]), faces)


def test_interpenetrating_cubes_intersect_and_clean_meshes_do_not():
    assert self_intersection_fraction(two_cubes(0.5)) > 0
    hit = self_intersecting_faces(two_cubes(0.5))
    assert 0 < hit.sum() < 12
    assert self_intersection_fraction(two_cubes(2.0)) == 0.0  # apart: no intersection
    for mesh in (cube_quads(), icosphere(2), prism(7), torus_grid(12, 8, 3)):
        assert self_intersection_fraction(mesh) == 0.0


def test_topology_flags():
    cube = cube_quads()
    assert topology_flags(cube) == {
        "manifold": True,
        "watertight": True,
        "oriented": True,
        "valid": True,
        "components": 1,
    }
    open_cube = PolygonMesh.from_faces(cube.vertices, cube.faces[1:])
    flags = topology_flags(open_cube)
    assert flags["manifold"] and not flags["watertight"] and not flags["valid"]
    faces = cube.faces
    faces[0] = faces[0][::-1]
    flags = topology_flags(PolygonMesh.from_faces(cube.vertices, faces))
    assert not flags["oriented"] and not flags["valid"]
    assert topology_flags(flip_faces(cube))["valid"]  # consistently inward is still oriented
    assert not topology_flags(PolygonMesh.empty())["valid"]


def test_edge_lengths_and_corner_angles():
    cube = cube_quads(2.0)
    assert np.allclose(edge_lengths(cube), 2.0) and len(edge_lengths(cube)) == 12
    assert np.allclose(corner_angles(cube), 90.0)
    angles = corner_angles(prism(5))
    assert np.isclose(angles, 108.0).sum() == 10 and np.isclose(angles, 90.0).sum() == 20
    assert np.allclose(corner_angles(icosphere(1)).reshape(-1, 3).sum(axis=1), 180.0)
    # a reflex corner of an L-shaped hexagon
    ell = PolygonMesh.from_faces(
        [[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]], [[0, 1, 2, 3, 4, 5]]
    )
    assert np.allclose(np.sort(corner_angles(ell)), [90, 90, 90, 90, 90, 270])


def test_distribution_distance():
    a = np.array([1.0, 2.0, 3.0])
    assert distribution_distance(a, a) == 0.0
    assert distribution_distance(a + 0.5, a) == pytest.approx(0.5)
    assert np.isnan(distribution_distance(np.zeros(0), a))


def test_an_open_surface_is_valid_only_when_declared_open():
    from spacemesh.primitives import faces_subset

    sphere = icosphere(2)
    cap, _ = faces_subset(sphere, sphere.face_normals()[:, 2] > 0).remove_unreferenced_vertices()
    closed_only = topology_flags(cap)
    declared = topology_flags(cap, open_surface=True)
    assert not closed_only["valid"] and declared["valid"]
    assert not closed_only["watertight"] and not declared["watertight"]
    assert declared["manifold"] and declared["oriented"]
    assert topology_flags(sphere, open_surface=True)["valid"]  # closed is valid either way
