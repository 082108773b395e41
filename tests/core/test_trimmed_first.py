"""An open surface's second candidate (:func:`fit_trimmed_first`): the decode trimmed to
the points before the geometry stage, then fitted. The stage fits an open mesh without
flipping it (its orientation is its points'), and the candidate is an oriented manifold
with rims whatever the scan's direction."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spacemesh.examples import icosphere
from spacemesh.geometry import GeometryOptions
from spacemesh.geometry.finishing import finish_geometry, fit_trimmed_first
from spacemesh.geometry.report import fit_score
from spacemesh.geometry.surface import face_support, open_surface, shape_surface
from spacemesh.primitives import flip_faces, sample_surface
from tests.validity import assert_valid_mesh


@pytest.fixture(scope="module")
def sphere_points():
    points, normals = sample_surface(icosphere(3), 3000, np.random.default_rng(0))
    return points.astype(np.float64), normals.astype(np.float64)


def one_sided(points, normals, direction):
    """The points seen from ``direction`` (their normal has a positive part along it)."""
    return points[normals @ np.asarray(direction, dtype=np.float64) > 0.0]


def upper_cap(inward: bool):
    """The upper half of a sphere, open, facing out (or in)."""
    sphere = icosphere(3)
    support = face_support(sphere, one_sided(*sample_surface(sphere, 3000,
                                                             np.random.default_rng(2)),
                                             [0, 0, 1]))
    cap, _ = open_surface(sphere, support)
    return flip_faces(cap) if inward else cap


@pytest.mark.parametrize("inward", [False, True])
def test_an_open_mesh_is_fitted_and_keeps_the_orientation_its_points_gave(sphere_points,
                                                                          inward):
    points, normals = sphere_points
    cap = upper_cap(inward)
    assert_valid_mesh(cap, open_surface=True)
    grown = cap.with_vertices(cap.vertices * 0.9)  # the fit must move it out to the points
    mesh, stats = finish_geometry(grown, one_sided(points, normals, [0, 0, 1]), None,
                                  GeometryOptions())
    report = assert_valid_mesh(mesh, open_surface=True)
    assert report.n_boundary_edges > 0 and stats["n_flipped"] == 0
    # fitted: the points lie on the unit sphere, the start 10% inside it
    assert np.linalg.norm(mesh.vertices, axis=1).mean() > 0.97
    # an open cap has no volume: its orientation is its points', never a signed volume's
    centroids = np.array([mesh.vertices[f].mean(axis=0) for f in mesh.faces])
    outward = np.einsum("ij,ij->i", mesh.face_normals(), centroids).mean()
    assert outward < 0 if inward else outward > 0


def test_a_complete_cloud_leaves_nothing_to_trim_first(sphere_points):
    points, _ = sphere_points
    assert fit_trimmed_first(icosphere(2), points, None, GeometryOptions()) is None


@pytest.mark.parametrize("direction", [[0, 0, 1], [0.3, -0.8, 0.5]])
@pytest.mark.parametrize("scale", [0.98, 0.85])
def test_a_one_sided_decode_is_trimmed_then_fitted_where_the_points_are(
        sphere_points, direction, scale):
    points, normals = sphere_points
    seen = one_sided(points, normals, direction)
    sphere = icosphere(3)  # a dense decode (642 vertices) near the points, or too far
    jitter = np.random.default_rng(1).normal(0.0, 0.01, sphere.vertices.shape)
    decode = sphere.with_vertices(sphere.vertices * scale + jitter)
    options = replace(GeometryOptions(), dense_factor=2.0)
    made = fit_trimmed_first(decode, seen, None, options, target_vertices=300)
    if scale < 0.9:  # no point reaches the loose decode: nothing to trim before the fit
        assert made is None
        return
    assert made is not None
    mesh, stats = made
    report = assert_valid_mesh(mesh, open_surface=True)
    assert report.n_boundary_edges > 0 and stats["faces_trimmed"] > 0
    # the same steps by hand
    early, _ = open_surface(decode, face_support(decode, seen))
    by_hand, _ = finish_geometry(early, seen, None, options, target_vertices=300)
    np.testing.assert_array_equal(mesh.vertices, by_hand.vertices)
    # fitted then trimmed, the closed mesh keeps fewer vertices on the seen side, and
    # here fits worse: every vertex of the second candidate is where the points are
    fitted, _ = finish_geometry(decode, seen, None, options, target_vertices=300)
    after, facts, _ = shape_surface(fitted, seen, None, "auto", options)
    assert facts.open and mesh.n_vertices == 300 > after.n_vertices
    assert fit_score(mesh, seen) < fit_score(after, seen)


@settings(max_examples=12, deadline=None, derandomize=True)
@given(direction=st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(
    lambda d: np.linalg.norm(d) > 0.2),
       scale=st.floats(0.95, 1.05), target=st.sampled_from([60, 120, 200]))
def test_any_one_sided_scan_gives_an_oriented_manifold_with_rims(sphere_points, direction,
                                                                  scale, target):
    points, normals = sphere_points
    seen = one_sided(points, normals, direction)
    decode = icosphere(2).with_vertices(icosphere(2).vertices * scale)  # 162 vertices
    made = fit_trimmed_first(decode, seen, None, GeometryOptions(), target_vertices=target)
    assert made is not None
    report = assert_valid_mesh(made[0], open_surface=True)
    assert report.n_nonmanifold_vertices == 0 and report.is_oriented
    assert report.n_boundary_edges > 0
