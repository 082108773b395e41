"""Planar polygons from flat regions (``face_type=polygons``).

Merging keeps the decode's guarantee: hypothesis draws the mesh (a triangulated box, a
sphere, a torus of quads, the sphere flattened to a disk) and the tolerance, and every
result is a closed oriented manifold over the same vertices, no face visits a vertex
twice, every corner lies within the tolerance of its face's plane, and no more faces
cross than before.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.geometry.polygons import face_planarity, merge_coplanar
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_faces
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


MESHES = {"cube": triangulated(cube_quads()), "box": box(), "sphere": icosphere(2),
          "torus": torus_grid(12, 8), "disk": icosphere(2).with_vertices(
              icosphere(2).vertices * [1.0, 1.0, 0.02])}


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


@settings(max_examples=40, deadline=None, derandomize=True)
@given(name=st.sampled_from(sorted(MESHES)),
       tolerance=st.sampled_from([0.0, 1e-6, 1e-3, 1e-2, 0.05, 0.3]))
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
