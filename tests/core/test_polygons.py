"""Planar polygons from flat regions (``face_type=polygons``).

Merging keeps the decode's guarantee: hypothesis draws the mesh (a triangulated box, a
sphere, a torus of quads, the sphere flattened to a disk) and the tolerance, and every
result is a closed oriented manifold over the same vertices, no face visits a vertex
twice, every corner lies within the tolerance of its face's plane, and no more faces
cross than before. With the collapses first (``collapse_flat``, the pipeline's order)
the same holds over fewer vertices, with the pieces and genus kept; a finely
triangulated box comes out as six quads on its eight corners.
"""

from __future__ import annotations

import numpy as np
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.geometry.polygons import collapse_flat, face_planarity, merge_coplanar
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_faces
from spacemesh.topology import surface_topology
from tests.validity import assert_valid_mesh


def triangulated(mesh: PolygonMesh) -> PolygonMesh:
    triangles, _ = triangulate_faces(mesh)
    return PolygonMesh(mesh.vertices, triangles.reshape(-1),
                       np.arange(0, triangles.size + 1, 3))


def box() -> PolygonMesh:
    """A 2 x 1 x 0.5 box of triangles with vertices inside its faces."""
    sphere = icosphere(2)
    v = sphere.vertices / np.abs(sphere.vertices).max(axis=1, keepdims=True)  # on the cube
    return sphere.with_vertices(v * [1.0, 0.5, 0.25])


def fine_box(subdivisions: int = 2) -> PolygonMesh:
    """A 2 x 1 x 0.5 box of triangles with vertices inside its faces and along its edges
    (each of its 12 triangles cut into 4, ``subdivisions`` times)."""
    mesh = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    for _ in range(subdivisions):
        mesh = mesh.subdivide()
    return PolygonMesh.from_faces(np.asarray(mesh.vertices), np.asarray(mesh.faces))


MESHES = {"cube": triangulated(cube_quads()), "box": box(), "sphere": icosphere(2),
          "torus": torus_grid(12, 8), "disk": icosphere(2).with_vertices(
              icosphere(2).vertices * [1.0, 1.0, 0.02]),
          "fine box": fine_box(), "triangle torus": triangulated(torus_grid(12, 8))}


def test_a_triangulated_cube_becomes_six_quads():
    merged, stats = merge_coplanar(MESHES["cube"], 1e-9)
    assert merged.n_faces == 6 and merged.degree_histogram() == {4: 6}
    assert stats["faces_merged"] == 6 and stats["face_planarity"] == 0.0
    assert_valid_mesh(merged)


def test_a_box_with_vertices_inside_its_faces_loses_most_faces_and_stays_flat():
    merged, stats = merge_coplanar(MESHES["box"], 1e-6)
    assert merged.n_faces < 0.5 * MESHES["box"].n_faces
    assert stats["face_planarity"] <= 1e-6
    assert_valid_mesh(merged)


def test_a_finely_triangulated_box_becomes_six_quads_on_its_corners():
    mesh = fine_box(3)  # 386 vertices, 768 triangles
    flat, stats = collapse_flat(mesh, 1e-6)
    assert stats["vertices_collapsed"] == mesh.n_vertices - 8
    merged, _ = merge_coplanar(flat, 1e-6)
    assert merged.n_vertices == 8 and merged.degree_histogram() == {4: 6}
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-0.5, 0.5) for z in (-0.25, 0.25)])
    assert np.allclose(np.sort(merged.vertices, axis=0), np.sort(corners, axis=0))
    assert_valid_mesh(merged)


def test_a_box_shaken_within_the_tolerance_still_loses_most_faces():
    mesh = fine_box(2)
    shake = np.random.default_rng(0).uniform(-1e-3, 1e-3, mesh.vertices.shape)
    shaken = mesh.with_vertices(mesh.vertices + shake)
    flat, _ = collapse_flat(shaken, 2e-3)
    merged, stats = merge_coplanar(flat, 2e-3)
    assert merged.n_faces <= 0.15 * mesh.n_faces and stats["face_planarity"] <= 2e-3
    assert_valid_mesh(merged)
    assert not self_intersecting_faces(merged).any()


def test_curved_surfaces_keep_their_vertices_under_a_small_tolerance():
    sphere = icosphere(2)  # no two neighbouring faces are coplanar
    flat, stats = collapse_flat(sphere, 1e-4)
    assert stats["vertices_collapsed"] == 0 and flat.n_vertices == sphere.n_vertices


def every_mesh_and_tolerance(test):
    """``test(name, tolerance)`` over the property meshes and tolerances up to 0.3."""
    return settings(max_examples=40, deadline=None, derandomize=True)(given(
        name=st.sampled_from(sorted(MESHES)),
        tolerance=st.sampled_from([0.0, 1e-6, 1e-3, 1e-2, 0.05, 0.3]))(test))


@every_mesh_and_tolerance
def test_merging_keeps_the_guarantee(name, tolerance):
    mesh = MESHES[name]
    merged, stats = merge_coplanar(mesh, tolerance)
    assert_valid_mesh(merged)
    assert merged.n_vertices == mesh.n_vertices
    assert merged.n_faces == mesh.n_faces - stats["faces_merged"]
    assert all(len(set(face)) == len(face) for face in merged.faces)
    assert face_planarity(merged) <= tolerance + 1e-12
    assert self_intersecting_faces(merged).sum() <= self_intersecting_faces(mesh).sum()
    if not stats["vertices_flattened"]:
        assert np.array_equal(merged.vertices, mesh.vertices)
    else:  # corners moved onto their planes, by about the tolerance at most
        assert np.abs(merged.vertices - mesh.vertices).max() <= 4 * tolerance + 1e-12


@every_mesh_and_tolerance
def test_collapsing_then_merging_keeps_the_guarantee(name, tolerance):
    mesh = MESHES[name]
    flat, stats = collapse_flat(mesh, tolerance)
    assert flat.n_vertices == mesh.n_vertices - stats["vertices_collapsed"]
    if not mesh.is_triangle_mesh():  # only triangle meshes collapse
        assert flat is mesh
    merged, _ = merge_coplanar(flat, tolerance)
    assert_valid_mesh(merged)
    before, after = surface_topology(mesh), surface_topology(merged)
    assert (after.pieces, after.genus) == (before.pieces, before.genus)
    assert all(len(set(face)) == len(face) for face in merged.faces)
    assert face_planarity(merged) <= tolerance + 1e-12
    assert self_intersecting_faces(merged).sum() <= self_intersecting_faces(mesh).sum()
