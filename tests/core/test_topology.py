import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.topology import (
    SurfaceTopology,
    check_topology,
    edge_connected_faces,
    surface_topology,
    vertex_connected_faces,
    weld_equal_positions,
)
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


def test_surface_topology_counts_pieces_genus_and_boundary_loops():
    sphere, torus = icosphere(1), torus_grid()
    assert surface_topology(sphere) == SurfaceTopology(pieces=1, genus=0, boundary_loops=0)
    assert surface_topology(torus) == SurfaceTopology(pieces=1, genus=1, boundary_loops=0)
    both = PolygonMesh.from_faces(
        np.concatenate([sphere.vertices, torus.vertices + 5.0]),
        sphere.faces + [np.asarray(f) + sphere.n_vertices for f in torus.faces])
    assert surface_topology(both) == SurfaceTopology(pieces=2, genus=1, boundary_loops=0)
    # the faces around vertex 0 removed: one rim; two faces far apart removed: two rims
    faces = sphere.faces
    around = [f for f in faces if 0 not in np.asarray(f).tolist()]
    assert surface_topology(PolygonMesh.from_faces(sphere.vertices, around)).boundary_loops == 1
    centres = np.array([sphere.vertices[np.asarray(f)].mean(axis=0) for f in faces])
    far = int(np.argmin(centres @ centres[0]))  # the face opposite face 0
    two_holes = [f for k, f in enumerate(faces) if k not in (0, far)]
    opened = surface_topology(PolygonMesh.from_faces(sphere.vertices, two_holes))
    assert opened == SurfaceTopology(pieces=1, genus=0, boundary_loops=2)


def test_surface_topology_welds_equal_positions_first():
    sphere = icosphere(1)
    corners = sphere.vertices[np.asarray(sphere.faces)].reshape(-1, 3)  # a triangle soup
    soup = PolygonMesh.from_faces(corners, np.arange(len(corners)).reshape(-1, 3))
    assert check_topology(soup).n_components == sphere.n_faces  # unwelded: all apart
    assert surface_topology(soup) == SurfaceTopology(pieces=1, genus=0, boundary_loops=0)
    assert weld_equal_positions(soup).n_vertices == sphere.n_vertices


def test_faces_sharing_a_vertex_are_vertex_connected_but_not_edge_connected():
    # two triangles meeting at vertex 2 only, and a cube far away
    cube = cube_quads()
    bow = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0, 2, 0], [1, 2, 0]], dtype=float)
    faces = [np.array([0, 1, 2]), np.array([2, 4, 3])] + [f + 5 for f in cube.faces]
    mesh = PolygonMesh.from_faces(np.concatenate([bow, cube.vertices + 5]), faces)
    n_edge, edge_label = edge_connected_faces(mesh)
    n_vertex, vertex_label = vertex_connected_faces(mesh)
    assert n_edge == 3 and edge_label.tolist() == [0, 1] + [2] * 6
    assert n_vertex == 2 and vertex_label.tolist() == [0, 0] + [1] * 6
    # only some faces: the others are -1 and join nothing
    chosen = np.zeros(mesh.n_faces, dtype=bool)
    chosen[[1, 4]] = True
    n_chosen, chosen_label = vertex_connected_faces(mesh, chosen)
    assert n_chosen == 2 and chosen_label.tolist() == [-1, 0, -1, -1, 1, -1, -1, -1]
    assert vertex_connected_faces(mesh, np.zeros(mesh.n_faces, dtype=bool))[0] == 0
