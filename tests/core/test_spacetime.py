import numpy as np
import pytest

from spacemesh.spacetime import (
    count_pairs_below_threshold,
    edges_below_threshold,
    pairwise_distance,
)


@pytest.mark.parametrize("distance", ["spacetime", "euclidean", "dot"])
def test_blocked_edges_match_dense(distance):
    rng = np.random.default_rng(1)
    x = rng.normal(size=(300, 16))
    dense = pairwise_distance(x, distance=distance)
    tau = float(np.quantile(dense, 0.05))
    i, j = np.nonzero(np.triu(dense < tau, k=1))
    expected = np.stack([i, j], 1)
    # tiny blocks force many chunks, including single-row ones
    got = edges_below_threshold(x, tau, distance, block_entries=300 * 7)
    np.testing.assert_array_equal(got, expected)
    assert count_pairs_below_threshold(x, tau, distance, block_entries=999) == len(expected)


def test_spacetime_formula_and_split():
    x = np.array([[1.0, 2.0, 0.0, 3.0], [0.0, 0.0, 1.0, 1.0]])
    # space = first 2 coords, time = last 2: |(1,2)|^2 - |(-1,2)|^2 = 5 - 5 = 0
    assert pairwise_distance(x, distance="spacetime")[0, 1] == pytest.approx(0.0)
    # three space coordinates: 1 + 4 + 1 - 4 = 2
    assert pairwise_distance(x, distance="spacetime", n_space=3)[0, 1] == pytest.approx(2.0)


def test_alive_mask_and_degree_bound():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(120, 8))
    alive = rng.random(120) < 0.5
    edges = edges_below_threshold(x, 0.0, alive=alive)
    assert alive[edges].all()
    capped = edges_below_threshold(x, 50.0, max_degree=5)
    degree = np.bincount(capped.ravel(), minlength=120)
    assert degree.max() <= 5
    assert len(capped) > 0


def test_twenty_thousand_vertices_fit_in_memory():
    """N = 20,000 is blocked: never a dense N x N float matrix."""
    rng = np.random.default_rng(3)
    x = rng.normal(size=(20_000, 16)).astype(np.float32)
    edges = edges_below_threshold(x, -40.0)
    assert edges.ndim == 2 and edges.shape[1] == 2
    assert np.all(edges[:, 0] < edges[:, 1])
