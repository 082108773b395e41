"""The client's own mesh readers and writers, without a server: every format the
service writes (as ``spacemesh.io`` writes it) reads back to the same polygons."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh_client._formats import FormatError, read_mesh, write_mesh
from spacemesh_client.mesh import Mesh, MeshStats

VERTICES = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]])
FACES = [np.array([0, 3, 2, 1]), np.array([0, 1, 4]), np.array([1, 2, 4]),
         np.array([2, 3, 4]), np.array([3, 0, 4])]  # a pyramid: a quad and four triangles
STATS = MeshStats(5, 5, 8, {3: 4, 4: 1}, True, True, True, 1, 0)


def same_polygons(faces, expected) -> bool:
    return [f.tolist() for f in faces] == [f.tolist() for f in expected]


@pytest.mark.parametrize("fmt", ["json", "obj", "off", "ply"])
def test_polygon_formats_round_trip(fmt):
    vertices, faces = read_mesh(write_mesh(VERTICES, FACES, fmt), fmt)
    assert np.array_equal(vertices, VERTICES) and same_polygons(faces, FACES)


@pytest.mark.parametrize("fmt", ["glb", "gltf", "obj", "off", "ply"])
def test_the_services_writers_are_read(fmt):
    io = pytest.importorskip("spacemesh.io")
    from spacemesh.mesh import PolygonMesh

    data = io.export_mesh(PolygonMesh.from_faces(VERTICES, FACES), fmt)
    vertices, faces = read_mesh(data, fmt)
    assert np.allclose(vertices, VERTICES)
    if fmt in ("glb", "gltf"):
        assert len(faces) == 6 and all(len(f) == 3 for f in faces)
        back = io.load_mesh(write_mesh(vertices, faces, fmt), file_type=fmt)
        assert back.n_faces == 6
    else:
        assert same_polygons(faces, FACES)
    if fmt == "ply":
        ascii_ply = io.ply.export_ply(PolygonMesh.from_faces(VERTICES, FACES), encoding="ascii")
        assert same_polygons(read_mesh(ascii_ply, "ply")[1], FACES)


def test_a_mesh_saves_in_any_format(tmp_path):
    mesh = Mesh(write_mesh(VERTICES, FACES, "obj"), "obj", STATS)
    assert mesh.media_type == "model/obj" and mesh.face_sizes.tolist() == [4, 3, 3, 3, 3]
    assert len(mesh.triangles()) == 6
    for fmt in ("obj", "off", "ply", "json", "glb", "gltf"):
        saved = mesh.save(tmp_path / f"m.{fmt}")
        vertices, faces = read_mesh(saved.read_bytes(), fmt)
        assert np.allclose(vertices, VERTICES) and len(faces) == (6 if "gl" in fmt else 5)
    with pytest.raises(FormatError):
        mesh.save(tmp_path / "noextension")
    with pytest.raises(FormatError):
        read_mesh(b"garbage", "ply")
    assert STATS.to_dict()["face_degrees"] == {"3": 4, "4": 1}
    headers = {"X-SpaceMesh-Vertices": "5", "X-SpaceMesh-Faces": "5", "X-SpaceMesh-Edges": "8",
               "X-SpaceMesh-Face-Degrees": "3:4,4:1", "X-SpaceMesh-Manifold": "true",
               "X-SpaceMesh-Closed": "true", "X-SpaceMesh-Oriented": "true",
               "X-SpaceMesh-Components": "1", "X-SpaceMesh-Genus": "0"}
    assert MeshStats.from_headers(headers) == STATS


FOLDED_VERTICES = np.array(
    [[-2.444, 0.253, -0.580], [-1.696, 2.112, -0.300], [-2.028, 1.715, -0.219],
     [-1.938, 1.617, -0.570], [-1.934, 0.739, -0.609]]
)
#: A valid closed polygon mesh (5 vertices, a quad, a pentagon, a triangle) whose
#: first-corner fans both use the diagonal 0-3: four triangles on one edge.
FOLDED_FACES = [np.array([0, 2, 3, 4]), np.array([0, 4, 3, 1, 2]), np.array([1, 3, 2])]


def undirected_edge_uses(triangles: np.ndarray) -> np.ndarray:
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)[1]


def test_triangulation_keeps_folded_polygon_meshes_manifold(tmp_path):
    mesh = Mesh(write_mesh(FOLDED_VERTICES, FOLDED_FACES, "obj"), "obj",
                MeshStats(5, 3, 6, {3: 1, 4: 1, 5: 1}, True, True, True, 1, 0))
    first_corner = np.concatenate(
        [np.stack([np.full(len(f) - 2, f[0]), f[1:-1], f[2:]], axis=1) for f in FOLDED_FACES])
    assert undirected_edge_uses(first_corner).max() == 4  # what a plain fan does
    assert undirected_edge_uses(mesh.triangles()).tolist() == [2] * 9
    vertices, triangles = mesh.triangulate()
    assert len(vertices) == 5 and len(triangles) == 6
    saved = read_mesh(mesh.save(tmp_path / "m.glb").read_bytes(), "glb")
    assert undirected_edge_uses(np.array(saved[1])).tolist() == [2] * 9


def test_a_face_with_no_free_fan_gets_a_centroid():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1],
                         [0.5, 0.5, -1]], float)
    faces = [np.array([0, 2, 4]), np.array([1, 3, 5]), np.array([0, 1, 2, 3])]
    mesh = Mesh(write_mesh(vertices, faces, "obj"), "obj",
                MeshStats(6, 3, 8, {3: 2, 4: 1}, False, False, True, 1, 0))
    out, triangles = mesh.triangulate()
    assert len(out) == 7 and np.allclose(out[6], [0.5, 0.5, 0])
    assert len(triangles) == 6 and undirected_edge_uses(triangles).max() == 2
    assert len(mesh.triangles()) == 4  # no centroid: the first corner's fan
