"""The strict validator rejects each kind of bad mesh, for the right reason."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.data.validate import triangles_intersect, validate_mesh
from spacemesh.mesh import PolygonMesh

CUBE_V = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
CUBE_Q = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def cube(offset=(0.0, 0.0, 0.0), quads: bool = False) -> PolygonMesh:
    faces = (
        CUBE_Q if quads else [t for q in CUBE_Q for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])]
    )
    return PolygonMesh.from_faces(CUBE_V + np.asarray(offset), faces)


def merge(a: PolygonMesh, b: PolygonMesh) -> PolygonMesh:
    faces = [list(f) for f in a.faces] + [list(f + a.n_vertices) for f in b.faces]
    return PolygonMesh.from_faces(np.vstack([a.vertices, b.vertices]), faces)


def test_valid_meshes_pass():
    assert validate_mesh(cube()) == []
    assert validate_mesh(cube(quads=True)) == []


def test_open_mesh():
    mesh = cube(quads=True)
    open_mesh = PolygonMesh.from_faces(mesh.vertices, [list(f) for f in mesh.faces][1:])
    assert "open_boundary" in validate_mesh(open_mesh)


def test_flipped_face():
    faces = [list(f) for f in cube(quads=True).faces]
    faces[0] = faces[0][::-1]
    assert "inconsistent_orientation" in validate_mesh(PolygonMesh.from_faces(CUBE_V, faces))


def test_inward_orientation():
    faces = [list(f)[::-1] for f in cube(quads=True).faces]
    assert validate_mesh(PolygonMesh.from_faces(CUBE_V, faces)) == ["inward_orientation"]


def test_two_components():
    assert "multiple_components" in validate_mesh(merge(cube(), cube((3.0, 0.0, 0.0))))


def test_pinched_vertex():
    # Two cubes sharing exactly one corner: vertex 6 of the first is vertex 0 of the second.
    a, b = cube(), cube((1.0, 1.0, 1.0))
    faces = [list(f) for f in a.faces]
    remap = np.arange(8) + 8
    remap[0] = 6
    faces += [list(remap[f]) for f in b.faces]
    vertices = np.vstack([a.vertices, b.vertices])
    mesh, _ = PolygonMesh.from_faces(vertices, faces).remove_unreferenced_vertices()
    assert "non_manifold_vertex" in validate_mesh(mesh)


def test_non_manifold_edge():
    # Three quads on one edge: a cube plus a fin sharing the edge (0, 1).
    vertices = np.vstack([CUBE_V, [[0, -1, -1], [1, -1, -1]]])
    faces = [*CUBE_Q, [0, 1, 9, 8], [8, 9, 1, 0]]
    assert "non_manifold_edge" in validate_mesh(PolygonMesh.from_faces(vertices, faces))


def test_self_intersection():
    # Two interpenetrating cubes (also two components; the intersection must be found too).
    causes = validate_mesh(merge(cube(), cube((0.5, 0.5, 0.5))))
    assert "self_intersection" in causes


def test_self_intersection_single_component():
    # A cube whose top corner is pushed through the bottom face.
    vertices = CUBE_V.copy()
    vertices[6] = [0.6, 0.6, -0.5]
    assert "self_intersection" in validate_mesh(cube().with_vertices(vertices))


def test_zero_area_face():
    # Split the edge (0, 1) at its midpoint; fan-triangulating the faces from 0 makes a
    # zero-area triangle (0, 8, 1).
    vertices = np.vstack([CUBE_V, [[0.5, 0.0, 0.0]]])
    bottom = [0, 3, 2, 1, 8]
    front = [0, 8, 1, 5, 4]
    polygons = [bottom, CUBE_Q[1], front, *CUBE_Q[3:]]
    triangles = [[p[0], p[i], p[i + 1]] for p in polygons for i in range(1, len(p) - 1)]
    mesh = PolygonMesh.from_faces(vertices, triangles)
    assert "zero_area_face" in validate_mesh(mesh)
    # As polygons (collinear corner kept) the same shape is valid.
    assert validate_mesh(PolygonMesh.from_faces(vertices, polygons)) == []


def test_sliver_face():
    vertices = np.vstack([CUBE_V, [[0.5, 0.0, 1e-7]]])
    bottom = [0, 3, 2, 1, 8]
    front = [0, 8, 1, 5, 4]
    polygons = [bottom, CUBE_Q[1], front, *CUBE_Q[3:]]
    triangles = [[p[0], p[i], p[i + 1]] for p in polygons for i in range(1, len(p) - 1)]
    assert "sliver_face" in validate_mesh(PolygonMesh.from_faces(vertices, triangles))


def test_duplicate_vertex():
    vertices = np.vstack([CUBE_V, [[1.0, 1.0, 1.0 + 1e-9]]])
    faces = [list(f) for f in cube(quads=True).faces]
    faces[1] = [4, 5, 8, 7]  # top face uses the twin of vertex 6
    causes = validate_mesh(PolygonMesh.from_faces(vertices, faces))
    assert "duplicate_vertex" in causes


def test_non_planar_polygon():
    vertices = CUBE_V.copy()
    vertices[4:, 2] += [0.45, -0.45, 0.45, -0.45]  # twists the top quad (and the sides)
    assert "non_planar_face" in validate_mesh(cube(quads=True).with_vertices(vertices))


@pytest.mark.parametrize(
    ("b", "expected"),
    [
        ([[2, 0, 0], [3, 0, 0], [2, 1, 0]], False),  # coplanar, apart
        ([[0.2, 0.2, 0], [3, 0.2, 0], [0.2, 3, 0]], True),  # coplanar, overlapping
        ([[0.2, 0.2, -1], [0.2, 0.2, 1], [3, 3, 0]], True),  # piercing
        ([[0.2, 0.2, 0.1], [3, 0.2, 0.1], [0.2, 3, 0.1]], False),  # parallel above
    ],
)
def test_triangle_pair_test(b, expected):
    a = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    assert triangles_intersect(a, np.asarray(b, dtype=float)) is expected
