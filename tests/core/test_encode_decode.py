import numpy as np
import pytest

from spacemesh.connectivity import Connectivity
from spacemesh.encode import encode_connectivity
from spacemesh.errors import NotManifoldError
from spacemesh.halfedge import HalfedgeMesh
from spacemesh.mesh import PolygonMesh
from spacemesh.permutation import group_by_degree, log_sinkhorn, mask_diagonal
from tests.factories import cube_quads, icosphere, prism, torus_grid

MESHES = {
    "triangles": lambda: icosphere(2),
    "quads": cube_quads,
    "ngons": lambda: prism(7),
    "mixed-genus1": lambda: torus_grid(10, 6, triangulate_every=3),
}


@pytest.mark.parametrize("name", MESHES)
def test_encode_round_trip(name):
    mesh = MESHES[name]()
    conn = encode_connectivity(mesh)
    assert HalfedgeMesh.from_connectivity(conn).problems() == []
    assert conn.to_mesh(mesh.vertices).face_key_set() == mesh.face_key_set()
    np.testing.assert_array_equal(conn.edges, mesh.edges)
    # every next relation (i, j, k): j -> i -> k appear consecutively in some face
    corners = {
        (int(f[a - 1]), int(f[a]), int(f[(a + 1) % len(f)]))
        for f in mesh.faces
        for a in range(len(f))
    }
    trip = conn.next_triplets()
    assert {(int(j), int(i), int(k)) for i, j, k in trip} == corners


def test_encode_rejects_open_mesh():
    cube = cube_quads()
    with pytest.raises(NotManifoldError, match="boundary"):
        encode_connectivity(PolygonMesh.from_faces(cube.vertices, cube.faces[1:]))


def ideal_decode(conn: Connectivity) -> Connectivity:
    """Decode with hand-made 'perfect' Phi logits (a large value at the successor)."""
    n = conn.n_vertices
    local = conn.local_successor()
    succ = np.empty_like(local)
    for degree, vertices in group_by_degree(conn.offsets).items():
        if degree < 2:
            continue
        slots = conn.offsets[vertices][:, None] + np.arange(degree)
        logits = np.zeros((len(vertices), degree, degree))
        np.put_along_axis(logits, local[slots][..., None], 20.0, axis=2)
        p = log_sinkhorn(mask_diagonal(logits))
        assert np.all(p.argmax(-1) == local[slots])
        succ[slots] = slots[:, :1] + local[slots]
    return Connectivity(n, conn.offsets, conn.neighbours, succ)


@pytest.mark.parametrize("name", MESHES)
def test_decode_of_exact_edges_and_orders(name):
    """An embedding whose edges are exact and whose Phi favour the successors decodes
    to the same faces; checks that encode and decode share one convention."""
    mesh = MESHES[name]()
    conn = encode_connectivity(mesh)
    assert ideal_decode(conn).to_mesh(mesh.vertices).face_key_set() == mesh.face_key_set()
