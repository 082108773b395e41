"""Normal estimation, screened Poisson, PSR*, ball pivoting and the repair baselines."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics import Reference, score_mesh, topology_flags
from spacemesh.primitives import sample_surface

pytest.importorskip("pymeshlab")

from spacemesh.baselines import (
    ball_pivoting,
    estimate_normals,
    fill_holes_trimesh,
    meshfix,
    orient_outward,
    psr_star,
    screened_poisson,
)


@pytest.fixture(scope="module")
def sphere():
    return icosphere(4)  # unit sphere, 2562 vertices


@pytest.fixture(scope="module")
def sphere_points(sphere):
    points, _ = sample_surface(sphere, 2048, np.random.default_rng(0))
    return points.astype(np.float64)


@pytest.fixture(scope="module")
def sphere_psr(sphere_points):
    return screened_poisson(sphere_points, estimate_normals(sphere_points))


def test_normals_are_estimated_and_oriented_outward(sphere_points):
    normals = estimate_normals(sphere_points)
    radial = sphere_points / np.linalg.norm(sphere_points, axis=1, keepdims=True)
    dots = np.einsum("pd,pd->p", normals, radial)
    assert np.mean(dots > 0.9) > 0.98
    assert np.allclose(orient_outward(sphere_points, -normals), normals)


def test_psr_of_sphere_points_is_a_closed_mesh_near_the_sphere(sphere, sphere_psr):
    assert topology_flags(sphere_psr)["valid"]
    radius = np.linalg.norm(sphere_psr.vertices, axis=1)
    assert np.abs(radius - 1.0).max() < 0.05
    row = score_mesh(sphere_psr, Reference.from_mesh(sphere, seed=0), seed=1)
    assert row["cd"] < 2e-3 and row["in"] < 0.05 and row["n_vertices"] > 1000


def test_psr_star_decimates_to_the_target(sphere_psr):
    star = psr_star(sphere_psr, 200)
    assert abs(star.n_vertices - 200) <= 10
    assert topology_flags(star)["valid"]


def test_ball_pivoting_interpolates_the_points(sphere_points):
    mesh = ball_pivoting(sphere_points, estimate_normals(sphere_points))
    assert mesh.n_faces > 1000
    distance, _ = cKDTree(sphere_points).query(mesh.vertices)
    assert distance.max() < 1e-6  # every vertex is an input point


def holed_sphere(removed: int = 3) -> PolygonMesh:
    """An icosphere without ``removed`` of the faces around vertex 0."""
    sphere = icosphere(2)
    return PolygonMesh.from_faces(sphere.vertices, sphere.faces[removed:])


def test_trimesh_fill_holes_closes_small_holes_only():
    holed = holed_sphere(2)  # a quad hole
    assert not topology_flags(holed)["watertight"]
    filled = fill_holes_trimesh(holed)
    assert topology_flags(filled)["valid"] and filled.n_vertices == holed.n_vertices
    assert not topology_flags(fill_holes_trimesh(holed_sphere(3)))["watertight"]  # a pentagon


def test_meshfix_closes_a_hole():
    pytest.importorskip("pymeshfix")
    fixed = meshfix(holed_sphere(3))
    assert topology_flags(fixed)["valid"]
