"""The decode's unpinch rule: a pinched face loses its weakest edge at a repeated vertex
(``DecodeOptions(unpinch="edge")``, the default) before any vertex is removed."""

from dataclasses import replace

import numpy as np
import pytest

from spacemesh.decode import DecodeOptions, decode, pinched_face_edges
from spacemesh.encode import encode_connectivity
from spacemesh.examples import icosphere, torus_grid
from spacemesh.fitting import EmbeddingFitConfig, fit_mesh
from spacemesh.metrics.connectivity import edge_f1_score
from spacemesh.spacetime import pairwise_distance


@pytest.fixture(scope="module", params=["icosphere", "torus"])
def fitted(request):
    """A mesh and the embeddings that the autodecoder fitted to it exactly."""
    mesh = icosphere(2) if request.param == "icosphere" else torus_grid(12, 8, 1)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=400, threads=1))
    assert result.exact
    return mesh, result.embeddings


def _with_false_edges(emb, n_false: int):
    """The embeddings with the threshold raised past the ``n_false`` closest non-edges
    (false positives that are weaker than every true edge)."""
    n = len(emb.adjacency)
    d = np.sort(pairwise_distance(emb.adjacency, distance="spacetime")[np.triu_indices(n, 1)])
    n_edges = int((d < emb.tau).sum())
    return replace(emb, tau=float(0.5 * (d[n_edges + n_false - 1] + d[n_edges + n_false])))


@pytest.mark.parametrize("n_false", [1, 10, 30])
def test_weak_false_edges_are_dropped_and_the_mesh_recovered(fitted, n_false):
    mesh, emb = fitted
    noisy = _with_false_edges(emb, n_false)
    # the edge rule alone, then with crossing diagonals dropped first (the default)
    alone = decode(mesh.vertices, noisy, DecodeOptions(uncross=False))
    assert alone.n_unpinch_edges == n_false and alone.n_unpinched == 0
    result = decode(mesh.vertices, noisy)
    assert result.n_uncrossed + result.n_unpinch_edges == n_false
    assert result.n_uncrossed > 0 or n_false < 30  # 30 false edges include diagonals
    assert result.n_unpinched == 0
    for decoded in (alone, result):
        assert decoded.mesh.n_vertices == mesh.n_vertices
        assert decoded.mesh.face_key_set() == mesh.face_key_set()
    # the vertex rule alone loses vertices and the edges around them
    vertex_rule = decode(mesh.vertices, noisy, DecodeOptions(unpinch="vertex", uncross=False))
    assert vertex_rule.n_unpinched > 0 and vertex_rule.mesh.n_vertices < mesh.n_vertices
    truth = encode_connectivity(mesh).edges
    assert edge_f1_score(vertex_rule.connectivity.edges, truth, mesh.n_vertices) < 1.0


def test_the_weakest_edge_at_the_repeated_vertex_goes():
    # one face 0-1-2-3-1-4 visits vertex 1 twice; another face 5-6-7 is simple
    indices = np.array([0, 1, 2, 3, 1, 4, 5, 6, 7])
    offsets = np.array([0, 6, 9])
    n = 8
    pairs = [(0, 1), (1, 2), (2, 3), (1, 3), (1, 4), (0, 4), (5, 6), (6, 7), (5, 7)]
    keys = np.array([i * n + j for i, j in pairs])
    distance = np.array([0.1, 0.2, 0.9, 0.3, 0.4, 0.95, 1.0, 1.0, 1.0])
    order = np.argsort(keys)
    drop = pinched_face_edges(indices, offsets, n, keys[order], distance[order])
    # (2, 3) and (0, 4) are weaker but do not touch vertex 1
    assert drop.tolist() == [1 * n + 4]
    none = pinched_face_edges(indices[6:], np.array([0, 3]), n, keys[order], distance[order])
    assert none.size == 0
