"""The graph primitives (spacemesh.primitives.graph): the one home of connected
components and of the uniform (umbrella) adjacency."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from spacemesh.primitives import component_labels, uniform_adjacency


def test_component_labels_numbers_components_by_first_node():
    # 0-3, 1-4, 4-5; node 2 and node 6 alone
    count, labels = component_labels(7, np.array([[3, 0], [1, 4], [5, 4]]))
    assert count == 4
    assert labels.dtype == np.int64
    assert labels.tolist() == [0, 1, 2, 0, 1, 1, 3]


@pytest.mark.parametrize("seed", range(5))
def test_component_labels_are_scipys_labels(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 80))
    pairs = rng.integers(0, n, size=(int(rng.integers(0, n)), 2))  # repeats, self pairs
    count, labels = component_labels(n, pairs)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    expected_count, expected = connected_components(graph, directed=False)
    assert count == expected_count
    np.testing.assert_array_equal(labels, expected)
    firsts = [int(np.flatnonzero(labels == k)[0]) for k in range(count)]
    assert firsts == sorted(firsts)


def test_component_labels_without_pairs_or_nodes():
    count, labels = component_labels(3, np.zeros((0, 2), dtype=np.int64))
    assert count == 3 and labels.tolist() == [0, 1, 2]
    count, labels = component_labels(0, np.zeros((0, 2), dtype=np.int64))
    assert count == 0 and labels.shape == (0,)


def test_uniform_adjacency_is_symmetric_with_unit_weights():
    # the directed sides of two triangles sharing side 1-2, one side repeated
    pairs = np.array([[0, 1], [1, 2], [2, 0], [2, 1], [1, 3], [3, 2], [0, 1]])
    w = uniform_adjacency(5, pairs)
    dense = w.toarray()
    assert w.shape == (5, 5) and dense.dtype == np.float64
    np.testing.assert_array_equal(dense, dense.T)
    assert set(np.unique(dense)) == {0.0, 1.0}
    assert dense.sum(axis=1).tolist() == [2, 3, 3, 2, 0]  # node 4 has no neighbour
    assert w.has_sorted_indices
    centroid = (w @ np.arange(5.0)) / np.maximum(dense.sum(axis=1), 1)
    assert centroid[0] == pytest.approx(1.5)  # mean of nodes 1 and 2
