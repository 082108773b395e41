import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology
from tests.factories import cube_quads, icosphere, prism, torus_grid


def test_closed_meshes_are_clean():
    for mesh, genus in [(cube_quads(), 0), (icosphere(2), 0), (prism(7), 0), (torus_grid(), 1)]:
        report = check_topology(mesh)
        assert report.is_closed_oriented_manifold, report.defects()
        assert report.genus == genus
        assert report.defects() == []


def test_open_mesh_reports_boundary():
    cube = cube_quads()
    open_mesh = PolygonMesh.from_faces(cube.vertices, cube.faces[:-1])
    report = check_topology(open_mesh)
    assert report.n_boundary_edges == 4
    assert not report.is_closed_oriented_manifold
    assert "boundary" in " ".join(report.defects())


def test_flipped_face_is_misoriented():
    cube = cube_quads()
    faces = cube.faces
    faces[0] = faces[0][::-1]
    report = check_topology(PolygonMesh.from_faces(cube.vertices, faces))
    assert report.n_misoriented_edges == 4
    assert not report.is_oriented


def test_pinched_vertex_and_nonmanifold_edge():
    v = np.random.default_rng(0).random((7, 3))
    tet_a = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    tet_b = [[0, 5, 4], [0, 4, 6], [0, 6, 5], [4, 5, 6]]
    report = check_topology(PolygonMesh.from_faces(v, tet_a + tet_b))
    assert report.n_nonmanifold_vertices == 1
    three_fins = [[0, 1, 2], [1, 0, 3], [0, 1, 4]]
    assert check_topology(PolygonMesh.from_faces(v, three_fins)).n_nonmanifold_edges == 1


def test_repeated_vertex_face():
    v = np.random.default_rng(0).random((5, 3))
    report = check_topology(PolygonMesh.from_faces(v, [[0, 1, 2, 0, 3, 4]]))
    assert report.n_repeated_vertex_faces == 1
    assert not report.is_manifold
