import numpy as np
import pytest

from spacemesh.matching import greedy_single_cycle, is_single_cycle, match_cycles, single_cycle_mask
from spacemesh.permutation import log_sinkhorn, mask_diagonal, reduction_logits


def test_sinkhorn_is_doubly_stochastic():
    rng = np.random.default_rng(0)
    logits = mask_diagonal(rng.normal(size=(50, 6, 6)) * 3)
    p = np.exp(log_sinkhorn(logits, n_iters=200))
    np.testing.assert_allclose(p.sum(1), 1, atol=1e-4)
    np.testing.assert_allclose(p.sum(2), 1, atol=1e-4)
    assert np.all(p[:, np.arange(6), np.arange(6)] == 0)


def test_product_reduction_is_eq6():
    rng = np.random.default_rng(1)
    root, prev, nxt = (
        rng.normal(size=(2, 4)),
        rng.normal(size=(2, 3, 4)),
        rng.normal(size=(2, 3, 4)),
    )
    logits = reduction_logits(root, prev, nxt, "product")
    expected = np.sum(root[1] * prev[1, 2] * nxt[1, 0])
    assert logits[1, 2, 0] == pytest.approx(expected)


def test_single_cycle_checks():
    assert is_single_cycle(np.array([1, 2, 0]))
    assert not is_single_cycle(np.array([1, 0, 2]))
    perms = np.array([[1, 2, 3, 0], [1, 0, 3, 2], [3, 0, 1, 2], [0, 1, 2, 3]])
    np.testing.assert_array_equal(single_cycle_mask(perms), [True, False, True, False])
    for p in perms:
        assert single_cycle_mask(p[None])[0] == is_single_cycle(p)


def test_greedy_always_single_cycle():
    rng = np.random.default_rng(2)
    for d in range(2, 12):
        for _ in range(20):
            perm = greedy_single_cycle(rng.normal(size=(d, d)))
            assert sorted(perm.tolist()) == list(range(d))
            assert is_single_cycle(perm)


def test_lap_then_fallback():
    # two 2-cycles are the optimal assignment: the greedy fallback must break them
    d = 4
    cost_two_cycles = np.full((d, d), -1e-3)
    for a, b in [(0, 1), (1, 0), (2, 3), (3, 2)]:
        cost_two_cycles[a, b] = 0.0
    log_phi = np.log(np.maximum(np.exp(cost_two_cycles * 50), 1e-12))[None]
    log_phi = log_sinkhorn(mask_diagonal(log_phi * 100))
    perms, n_fallbacks = match_cycles(log_phi)
    assert n_fallbacks == 1
    assert is_single_cycle(perms[0])
