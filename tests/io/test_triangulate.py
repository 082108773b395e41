"""Triangulation of single polygons and of polygon meshes, keeping orientation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import spacemesh.triangulate as tri
from spacemesh.mesh import PolygonMesh
from spacemesh.triangulate import newell_normal, triangulate_faces, triangulate_polygon

L_SHAPE = np.array(
    [[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]], dtype=np.float64
)


@pytest.fixture(params=["earcut", "builtin"])
def backend(request, monkeypatch):
    """Run a test with mapbox_earcut (when installed) and with the built-in clipper."""
    if request.param == "earcut":
        if tri._mapbox_earcut is None:
            pytest.skip("mapbox_earcut is not installed")
    else:
        monkeypatch.setattr(tri, "_mapbox_earcut", None)
    return request.param


def triangle_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T, 3) unnormalised normals (twice the vector areas)."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    return np.cross(b - a, c - a)


def check_triangulation(points: np.ndarray, triangles: np.ndarray) -> None:
    """n - 2 triangles, each counter-clockwise about the normal, covering the area."""
    n = len(points)
    assert triangles.shape == (n - 2, 3)
    assert triangles.dtype == np.int64
    assert set(np.unique(triangles)) <= set(range(n))
    normal = newell_normal(points)
    unit = normal / np.linalg.norm(normal)
    doubled = triangle_normals(points, triangles) @ unit  # (T,) twice the signed areas
    scale = np.ptp(points, axis=0).max() ** 2
    assert np.all(doubled > -1e-9 * scale)
    assert doubled.sum() == pytest.approx(np.linalg.norm(normal), rel=1e-9, abs=1e-12 * scale)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


@st.composite
def star_polygons(draw):
    """A simple polygon star-shaped about the origin, placed at random in 3D."""
    n = draw(st.integers(min_value=3, max_value=24))
    gaps = np.array(draw(st.lists(st.floats(0.2, 1.0), min_size=n, max_size=n)))
    angles = np.cumsum(gaps / gaps.sum() * 2 * np.pi)
    radii = np.array(draw(st.lists(st.floats(0.15, 1.0), min_size=n, max_size=n)))
    flat = np.stack([radii * np.cos(angles), radii * np.sin(angles), np.zeros(n)], axis=1)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    scale = draw(st.sampled_from([1e-3, 1.0, 250.0]))
    return (flat * scale) @ random_rotation(rng).T + rng.normal(size=3) * scale


@settings(max_examples=150, deadline=None)
@given(points=star_polygons())
def test_star_polygons_builtin(points):
    original, tri._mapbox_earcut = tri._mapbox_earcut, None
    try:
        check_triangulation(points, triangulate_polygon(points))
    finally:
        tri._mapbox_earcut = original


@settings(max_examples=150, deadline=None)
@given(points=star_polygons())
def test_star_polygons_default_backend(points):
    check_triangulation(points, triangulate_polygon(points))


@settings(max_examples=60, deadline=None)
@given(points=star_polygons())
def test_reversed_polygon_gives_reversed_orientation(points):
    reversed_points = points[::-1]
    triangles = triangulate_polygon(reversed_points)
    check_triangulation(reversed_points, triangles)
    normal = newell_normal(reversed_points)
    assert np.dot(newell_normal(points), normal) < 0


def test_square_is_fanned():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64)
    assert triangulate_polygon(square).tolist() == [[0, 1, 2], [0, 2, 3]]


def test_l_shape(backend):
    triangles = triangulate_polygon(L_SHAPE)
    check_triangulation(L_SHAPE, triangles)
    assert triangle_normals(L_SHAPE, triangles)[:, 2].sum() == pytest.approx(6.0)


def test_non_convex_comb(backend):
    # A comb: a bottom edge, then teeth of heights 3 and 1 from right to left.
    teeth = [[x, 3.0 if x % 2 == 0 else 1.0, 0.0] for x in range(8, -1, -1)]
    points = np.array([[0.0, 0.0, 0.0], [8.0, 0.0, 0.0], *teeth])
    assert newell_normal(points)[2] > 0
    check_triangulation(points, triangulate_polygon(points))


def test_collinear_corners_do_not_make_empty_triangles():
    # A rectangle with extra corners along its edges is convex: fanned from a true corner.
    points = np.array(
        [[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64
    )
    triangles = triangulate_polygon(points)
    check_triangulation(points, triangles)
    assert np.all(np.abs(triangle_normals(points, triangles)[:, 2]) > 1e-12)


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((5, 3)),  # all in one point
        np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], dtype=np.float64),  # a line
        np.array([[0, 0, 0], [1, 1, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64),  # bowtie
        np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0], [0, 1, 0]]),  # NaN
        np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 0], [1, 1, 0]]),  # spike
    ],
)
def test_degenerate_polygons_never_fail(points, backend):
    triangles = triangulate_polygon(points)
    assert triangles.shape == (len(points) - 2, 3)
    assert triangles.min() >= 0 and triangles.max() < len(points)


def test_small_polygons():
    assert triangulate_polygon(np.zeros((2, 3))).shape == (0, 3)
    assert triangulate_polygon(np.eye(3)).tolist() == [[0, 1, 2]]


def test_large_non_convex_builtin(monkeypatch):
    monkeypatch.setattr(tri, "_mapbox_earcut", None)
    n = 400
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    radii = np.where(np.arange(n) % 2 == 0, 1.0, 0.5)
    points = np.stack([radii * np.cos(angles), radii * np.sin(angles), np.zeros(n)], axis=1)
    check_triangulation(points, triangulate_polygon(points))


# ---------------------------------------------------------------------- meshes
def mixed_mesh() -> PolygonMesh:
    """A triangle, a square, an L-shaped hexagon and a pentagon, side by side."""
    vertices = np.concatenate(
        [
            np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64),
            np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]) + np.array([3.0, 0, 0]),
            L_SHAPE + np.array([6.0, 0, 0]),
            np.array([[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0, 2 * np.pi, 6)[:5]]),
        ]
    )
    faces = [[0, 1, 2], [3, 4, 5, 6], list(range(7, 13)), list(range(13, 18))]
    return PolygonMesh.from_faces(vertices, faces)


def test_triangle_mesh_fast_path():
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = PolygonMesh.from_faces(np.eye(4, 3), faces)
    triangles, source = triangulate_faces(mesh)
    assert triangles.tolist() == faces.tolist()
    assert source.tolist() == [0, 1]


def test_mixed_mesh_matches_per_polygon(backend):
    mesh = mixed_mesh()
    triangles, source = triangulate_faces(mesh)
    assert len(triangles) == int(np.sum(mesh.face_sizes - 2))
    assert np.all(np.diff(source) >= 0)
    assert np.bincount(source).tolist() == (mesh.face_sizes - 2).tolist()
    for f, face in enumerate(mesh.faces):
        expected = face[triangulate_polygon(mesh.vertices[face])]
        assert triangles[source == f].tolist() == expected.tolist()
    normals = triangle_normals(mesh.vertices, triangles)
    assert np.all(np.einsum("ij,ij->i", normals, mesh.face_normals()[source]) > 0)
    assert mesh.triangulate()[0].tolist() == triangles.tolist()


def test_convex_faces_avoid_zero_area_fan_triangles():
    # Corners 0, 1, 2 are collinear: a fan from corner 0 would hold the zero-area
    # triangle (0, 1, 2); the fan starts at corner 1 (between two true corners).
    points = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], dtype=np.float64)
    mesh = PolygonMesh.from_faces(points, [[0, 1, 2, 3, 4], [0, 1, 2, 3, 4]])
    triangles, _ = triangulate_faces(mesh)
    areas = triangle_normals(mesh.vertices, triangles)[:, 2]
    assert np.all(areas > 1e-12)
    assert areas.sum() == pytest.approx(2 * 2 * 2.0)
    assert triangulate_polygon(points).tolist() == triangles[:3].tolist()


def test_faces_with_fewer_than_three_corners_give_nothing():
    mesh = PolygonMesh.from_faces(np.eye(4, 3), [[0, 1], [0, 1, 2, 3], [2]])
    triangles, source = triangulate_faces(mesh)
    assert source.tolist() == [1, 1]
    assert triangles.shape == (2, 3)


def test_empty_mesh():
    triangles, source = triangulate_faces(PolygonMesh.empty())
    assert triangles.shape == (0, 3) and source.shape == (0,)
