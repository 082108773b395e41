"""Long faces cut along their strongest missing diagonal (``DecodeOptions.max_sides``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from spacemesh.decode import DecodeOptions, decode
from spacemesh.decode.splitting import split_long_faces
from spacemesh.encode import encode_connectivity
from spacemesh.examples import cube_quads, prism
from spacemesh.spacetime import distance_operands, pairwise_distance
from spacemesh.topology import check_topology


def _euclidean_operands(points: np.ndarray):
    return distance_operands(points, "euclidean", None)


def test_a_quad_cube_becomes_twelve_triangles_along_the_closest_diagonals():
    cube = cube_quads()
    connectivity = encode_connectivity(cube)
    # embeddings: the positions, with vertices 0 and 6 pulled toward each other's faces
    x = cube.vertices.copy()
    x[0] *= 0.9
    x[6] *= 0.9
    result, added = split_long_faces(connectivity, _euclidean_operands(x), 3)
    assert added == 6
    mesh = result.to_mesh(cube.vertices)
    assert np.diff(mesh.face_offsets).tolist() == [3] * 12
    assert check_topology(mesh).is_closed_oriented_manifold
    # each face took the diagonal with the smaller distance
    d = pairwise_distance(x, None, "euclidean")
    old = {tuple(e) for e in connectivity.edges.tolist()}
    for a, b in {tuple(e) for e in result.edges.tolist()} - old:
        face = next(f.tolist() for f in cube.faces if a in f and b in f)
        c, e = [v for v in face if v not in (a, b)]
        assert d[a, b] <= d[c, e]
    unchanged, none = split_long_faces(connectivity, _euclidean_operands(x), 4)
    assert none == 0 and unchanged is connectivity


def test_a_prism_cap_is_fully_triangulated_and_stays_manifold():
    mesh = prism(7)  # two 7-gons and seven quads
    rng = np.random.default_rng(0)
    result, added = split_long_faces(encode_connectivity(mesh),
                                     _euclidean_operands(rng.normal(size=(14, 4))), 3)
    assert added == 2 * 4 + 7
    out = result.to_mesh(mesh.vertices)
    assert (np.diff(out.face_offsets) == 3).all()
    assert check_topology(out).is_closed_oriented_manifold


def test_max_sides_below_three_is_refused():
    with pytest.raises(ValueError, match="at least 3"):
        split_long_faces(encode_connectivity(cube_quads()), _euclidean_operands(np.eye(8)), 2)


@pytest.mark.parametrize("n_missing", [1, 5])
def test_missed_edges_of_a_triangle_mesh_are_recovered(fitted, n_missing):
    mesh, emb = fitted
    n = mesh.n_vertices
    d = np.sort(pairwise_distance(emb.adjacency, distance="spacetime")[np.triu_indices(n, 1)])
    n_edges = int((d < emb.tau).sum())
    # the threshold lowered below the n_missing weakest true edges
    low = replace(emb, tau=float(0.5 * (d[n_edges - n_missing - 1] + d[n_edges - n_missing])))
    polygons = decode(mesh.vertices, low)
    assert polygons.mesh.face_key_set() != mesh.face_key_set()
    assert (np.diff(polygons.mesh.face_offsets) > 3).any()
    triangles = decode(mesh.vertices, low, DecodeOptions(max_sides=3))
    assert triangles.n_split == n_missing
    assert triangles.mesh.face_key_set() == mesh.face_key_set()
