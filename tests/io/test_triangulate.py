"""Triangulation of single polygons and of polygon meshes, keeping orientation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import spacemesh.primitives.triangles as tri
from spacemesh.decode import DecodeOptions, Embeddings, decode
from spacemesh.examples import torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    newell_normal,
    triangulate_faces,
    triangulate_manifold,
    triangulate_polygon,
)
from spacemesh.spacetime import pairwise_distance
from spacemesh.topology import check_topology

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
    assert triangulate_faces(mesh)[0].tolist() == triangles.tolist()


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


# --------------------------------------------------------------- manifold triangulation
def edge_uses(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How often each undirected and each directed triangle edge occurs."""
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    _, undirected_counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    _, directed_counts = np.unique(directed, axis=0, return_counts=True)
    return undirected_counts, directed_counts


def test_shared_diagonal_is_re_fanned():
    """A valid 5-vertex polygon sphere (the shipped model once returned it) whose
    geometric fans share the diagonal 0-3: four triangles on one edge. The manifold
    triangulation picks other fans and adds no vertex."""
    vertices = np.array(
        [[-2.444, 0.253, -0.580], [-1.696, 2.112, -0.300], [-2.028, 1.715, -0.219],
         [-1.938, 1.617, -0.570], [-1.934, 0.739, -0.609]]
    )
    mesh = PolygonMesh.from_faces(vertices, [[0, 2, 3, 4], [0, 4, 3, 1, 2], [1, 3, 2]])
    assert check_topology(mesh).is_closed_oriented_manifold
    plain, _ = triangulate_faces(mesh)
    assert edge_uses(plain)[0].max() == 4  # the defect this guards against
    out_vertices, triangles, source = triangulate_manifold(mesh)
    assert len(out_vertices) == 5
    assert np.array_equal(np.bincount(source), mesh.face_sizes - 2)
    report = check_topology(PolygonMesh.from_faces(out_vertices, triangles))
    assert report.is_closed_oriented_manifold, report.defects()


def test_blocked_face_gets_a_centroid():
    """Both diagonals of the quad are sides of other faces: no fan is free."""
    vertices = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1], [0.5, 0.5, -1]], float
    )
    mesh = PolygonMesh.from_faces(vertices, [[0, 1, 2, 3], [0, 2, 4], [1, 3, 5]])
    out_vertices, triangles, source = triangulate_manifold(mesh)
    assert len(out_vertices) == 7
    assert np.allclose(out_vertices[6], [0.5, 0.5, 0])  # the quad's centroid
    assert np.array_equal(np.bincount(source), [4, 1, 1])
    undirected, directed = edge_uses(triangles)
    assert undirected.max() == 2 and directed.max() == 1
    # every side of the quad is kept with its direction
    quad_triangles = triangles[source == 0]
    sides = {tuple(e) for t in quad_triangles for e in (t[[0, 1]], t[[1, 2]], t[[2, 0]])}
    assert {(0, 1), (1, 2), (2, 3), (3, 0)} <= sides


def test_clean_meshes_are_unchanged():
    mesh = torus_grid(6, 4)
    triangles, source = triangulate_faces(mesh)
    out_vertices, same_triangles, same_source = triangulate_manifold(mesh)
    assert out_vertices is mesh.vertices
    assert np.array_equal(triangles, same_triangles) and np.array_equal(source, same_source)


@settings(max_examples=120, deadline=None)
@given(st.integers(4, 40), st.integers(0, 2**32 - 1), st.sampled_from([0.0, 0.1, 0.3]))
def test_decoded_meshes_triangulate_to_manifolds(n, seed, quantile):
    """Random embeddings decode to closed oriented polygon manifolds (often tiny and
    folded); their manifold triangulation is a closed oriented triangle manifold too."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 8))
    d = pairwise_distance(x)[np.triu_indices(n, 1)]
    tau = float(np.quantile(d, quantile))
    emb = Embeddings(x, tau, *(rng.normal(size=(n, 4)) for _ in range(3)))
    mesh = decode(rng.normal(size=(n, 3)), emb, DecodeOptions(fallback="greedy")).mesh
    if mesh.n_faces == 0:
        return
    out_vertices, triangles, _ = triangulate_manifold(mesh)
    assert np.array_equal(out_vertices[: mesh.n_vertices], mesh.vertices)
    centroids = len(out_vertices) - mesh.n_vertices
    assert len(triangles) == int((mesh.face_sizes - 2).sum()) + 2 * centroids
    report = check_topology(PolygonMesh.from_faces(out_vertices, triangles))
    assert report.is_closed_oriented_manifold, report.defects()
