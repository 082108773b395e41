"""Edge collapses with the points' quadrics (spacemesh.geometry.simplify): the count asked
for, a closed oriented manifold with the same pieces and genus, no crossing faces, faces
that are the input's reduced by collapses, and creases kept where the points have them."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import icosphere, torus_grid
from spacemesh.geometry.intersections import self_intersection_fraction
from spacemesh.geometry.simplify import point_quadrics, simplify
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface
from spacemesh.topology import surface_topology
from tests.validity import assert_valid_mesh


def _points(mesh: PolygonMesh, count: int = 3000, seed: int = 0):
    return sample_surface(mesh, count, np.random.default_rng(seed))


def _triangulated(mesh: PolygonMesh) -> PolygonMesh:
    from spacemesh.primitives import triangles_of

    tri, _ = triangles_of(mesh)
    return PolygonMesh(mesh.vertices, tri.reshape(-1), np.arange(0, 3 * len(tri) + 1, 3))


def _canonical(face) -> tuple[int, ...]:
    """A face as a tuple starting at its smallest vertex (orientation kept)."""
    face = [int(v) for v in face]
    k = face.index(min(face))
    return tuple(face[k:] + face[:k])


def _check(source: PolygonMesh, result) -> None:
    out = result.mesh
    assert_valid_mesh(out)
    before, after = surface_topology(source), surface_topology(out)
    assert (after.pieces, after.genus) == (before.pieces, before.genus)
    assert self_intersection_fraction(out) == 0.0
    # every face is an input face with its vertices mapped through the collapses
    mapped = {_canonical(result.vertex_map[f]) for f in source.face_indices.reshape(-1, 3)}
    assert {_canonical(f) for f in out.face_indices.reshape(-1, 3)} <= mapped


def test_an_ellipsoid_is_collapsed_to_the_count_asked_for():
    mesh = icosphere(4)
    mesh = mesh.with_vertices(mesh.vertices * [1.0, 0.6, 0.3])
    points, _ = _points(mesh)
    result = simplify(mesh, points, target_vertices=150)
    assert result.mesh.n_vertices == 150 and result.stats["collapsed"] == mesh.n_vertices - 150
    _check(mesh, result)
    # the surface stays on the points: every point within 2% of the diagonal of the mesh
    from spacemesh.geometry import fit_report

    assert fit_report(result.mesh, points).points_to_mesh_mean_rel < 0.004


@pytest.mark.parametrize("target", [40, 12])
def test_a_torus_keeps_its_genus_and_two_spheres_their_pieces(target):
    torus = _triangulated(torus_grid(24, 12))
    points, _ = _points(torus)
    result = simplify(torus, points, target_vertices=target)
    _check(torus, result)
    assert surface_topology(result.mesh).genus == 1
    sphere = icosphere(3)
    shifted = sphere.vertices + np.array([3.0, 0.0, 0.0])
    two = PolygonMesh(np.concatenate([sphere.vertices, shifted]),
                      np.concatenate([sphere.face_indices,
                                      sphere.face_indices + sphere.n_vertices]),
                      np.arange(0, 6 * sphere.n_faces + 1, 3))
    points, _ = _points(two)
    result = simplify(two, points, target_vertices=target)
    _check(two, result)
    assert surface_topology(result.mesh).pieces == 2
    assert result.mesh.n_vertices >= 8  # no piece below a tetrahedron


def test_the_points_planes_keep_a_cubes_corners():
    """A finely tessellated cube whose points lie on its faces collapses onto its
    corners: the quadrics come from the points, so creases cost and stay."""
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0)).subdivide().subdivide().subdivide()
    mesh = PolygonMesh.from_faces(np.asarray(box.vertices), np.asarray(box.faces))
    points, normals = _points(mesh, 6000)  # the planes of the faces under the points
    result = simplify(mesh, points, normals, target_vertices=30)
    _check(mesh, result)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    nearest = np.linalg.norm(corners[:, None] - result.mesh.vertices[None], axis=2).min(axis=1)
    assert nearest.max() < 0.02  # every corner kept (2 is the edge length)
    # and the faces stay on the cube's planes
    assert np.abs(result.mesh.vertices).max(axis=1).min() > 0.98


def test_point_quadrics_measure_squared_distances_to_the_points_planes():
    vertices = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    points = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.0], [0.2, -0.1, 0.0]])
    normals = np.tile([0.0, 0.0, 2.0], (3, 1))  # not unit: normalised
    quadrics = point_quadrics(vertices, points, normals)
    h = np.array([0.3, -0.2, 0.5, 1.0])
    assert h @ quadrics[0] @ h == pytest.approx(3 * 0.5**2)
    assert np.all(quadrics[1] == 0)  # no point is nearest to the far vertex


def test_small_or_polygon_meshes_come_back_unchanged():
    mesh = icosphere(1)
    points, _ = _points(mesh)
    result = simplify(mesh, points, target_vertices=mesh.n_vertices)
    assert result.mesh is mesh and result.stats["collapsed"] == 0
    from spacemesh.examples import cube_quads

    cube = cube_quads()
    assert simplify(cube, _points(cube)[0], target_vertices=4).mesh is cube


def _fine_box() -> PolygonMesh:
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0)).subdivide().subdivide()
    return PolygonMesh.from_faces(np.asarray(box.vertices), np.asarray(box.faces))


@pytest.mark.parametrize("max_error", [1e-4, 1e-3, 1e-2])
def test_stop_at_error_makes_no_collapse_over_it(max_error):
    """``max_error``: no collapse whose error (a mean squared distance from the planes
    its vertex gathered) exceeds it, whatever the count; on an ellipsoid (no two faces
    coplanar) a larger error allows more collapses."""
    mesh = icosphere(3)
    mesh = mesh.with_vertices(mesh.vertices * [1.0, 0.6, 0.3])
    result = simplify(mesh, None, max_error=max_error)
    _check(mesh, result)
    assert 0 < result.stats["collapsed"] < mesh.n_vertices - 4
    assert 0 < result.stats["max_error"] <= max_error
    # the surface stays within about the error's distance of where it was
    from spacemesh.geometry import fit_report

    points, _ = _points(mesh)
    assert fit_report(result.mesh, points).points_to_mesh_p95 < 3 * np.sqrt(max_error)
    fewer = simplify(mesh, None, max_error=max_error / 10)
    assert fewer.stats["collapsed"] < result.stats["collapsed"]


def test_stop_at_error_collapses_a_box_onto_its_corners_and_no_further():
    mesh = _fine_box()
    result = simplify(mesh, None, max_error=1e-9)  # flat collapses cost nothing
    _check(mesh, result)
    assert result.mesh.n_vertices == 8 and result.stats["max_error"] <= 1e-9
    assert np.allclose(np.abs(result.mesh.vertices), 1.0)
    # the points' planes (estimated normals, blurred at the creases) cost more there
    points, _ = _points(mesh)
    assert simplify(mesh, points, max_error=1e-9).mesh.n_vertices > 8


def test_an_open_mesh_keeps_its_boundary():
    mesh = _fine_box()
    centres = mesh.vertices[mesh.face_indices.reshape(-1, 3)].mean(axis=1)
    keep = centres[:, 2] < 0.99  # the top face removed: a boundary loop
    tri = mesh.face_indices.reshape(-1, 3)[keep]
    used = np.unique(tri)
    index = np.full(mesh.n_vertices, -1)
    index[used] = np.arange(len(used))
    opened = PolygonMesh(mesh.vertices[used], index[tri].reshape(-1),
                         np.arange(0, 3 * len(tri) + 1, 3))
    result = simplify(opened, None, max_error=1e-9)
    assert_valid_mesh(result.mesh, open_surface=True)
    rim = np.isclose(opened.vertices[:, 2], 1.0)
    kept = {tuple(v) for v in result.mesh.vertices}
    assert all(tuple(v) in kept for v in opened.vertices[rim])  # every rim vertex stays
    assert result.mesh.n_vertices < opened.n_vertices - 20
