"""The inpainting sampler: alignment, held vertices, determinism."""

from __future__ import annotations

import numpy as np
from repair_testing import NoiseBackend, make_spec

from spacemesh.repair.inpaint import align, inpaint_tokens


def test_align_recovers_a_permutation_of_scaled_targets():
    rng = np.random.default_rng(0)
    targets = rng.uniform(-1, 1, (50, 3))
    order = rng.permutation(50)
    tokens = 0.7 * targets[order] + rng.normal(0, 1e-3, (50, 3))
    token = align(tokens, targets, scale=0.7)
    assert np.array_equal(order[token], np.arange(50))


def run(seed: int, steps: int = 8, method: str = "ddim"):
    spec = make_spec(max_vertices=32, steps=steps)
    rng = np.random.default_rng(seed)
    known = rng.uniform(-1, 1, (20, 3))
    hole = rng.uniform(-0.2, 0.2, (12, 3))
    backend = NoiseBackend()
    done = []
    result = inpaint_tokens(backend, backend.encode(np.zeros((1, 8, 3))), known, hole,
                            spec.schedule.respaced(steps), method=method,
                            rng=np.random.default_rng(seed),
                            progress=lambda d, t: done.append((d, t)))
    return known, result, done


def test_known_vertices_are_held_exactly():
    for method in ("ddim", "ddpm"):
        known, result, done = run(3, method=method)
        assert result.tokens.shape == (32, 4)
        assert len(np.unique(result.known_token)) == 20
        np.testing.assert_allclose(result.tokens[result.known_token, :3], known, atol=1e-6)
        assert np.all(result.tokens[result.known_token, 3] == 1.0)
        assert result.free.sum() == 12 and not result.alive[~result.free].any()
        assert np.array_equal(result.alive, result.free & (result.tokens[:, 3] > 0))
        assert done == [(i, 8) for i in range(1, 9)]


def test_same_seed_same_tokens():
    _, a, _ = run(5)
    _, b, _ = run(5)
    _, c, _ = run(6)
    assert np.array_equal(a.tokens, b.tokens)
    assert not np.array_equal(a.tokens, c.tokens)
