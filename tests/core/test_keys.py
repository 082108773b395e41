"""Edge keys (spacemesh.primitives.keys): the one way vertex pairs are compared, counted
and made unique."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.primitives import edge_keys, unique_edges


@pytest.mark.parametrize("n_vertices", [1, 7, 300])
def test_unique_edges_are_numpys_sorted_unique_rows(n_vertices):
    rng = np.random.default_rng(n_vertices)
    pairs = rng.integers(0, n_vertices, size=(4 * n_vertices, 2))  # repeats, both orders
    edges, counts = unique_edges(pairs, n_vertices, return_counts=True)
    expected, expected_counts = np.unique(np.sort(pairs, axis=1), axis=0, return_counts=True)
    assert edges.dtype == np.int64 and edges.shape == expected.shape
    assert np.array_equal(edges, expected) and np.array_equal(counts, expected_counts)
    assert unique_edges(np.zeros((0, 2), dtype=np.int64), n_vertices).shape == (0, 2)


def test_an_edge_has_one_key_whichever_way_it_runs():
    pairs = np.array([[3, 5], [5, 3], [0, 9]])
    keys = edge_keys(pairs, 10)
    assert keys.tolist() == [35, 35, 9]
