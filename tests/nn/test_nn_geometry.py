"""Local-geometry features of the connectivity network against brute-force numpy."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.geometry import (  # noqa: E402
    FAR,
    MOMENT_CHANNELS,
    OFFSET_SCALE,
    neighbour_offsets,
    offset_moments,
)


def _reference_neighbours(p: np.ndarray, valid: np.ndarray, k: int) -> np.ndarray:
    """Offsets and squared lengths to the k nearest other real vertices, one vertex at a time."""
    n = len(p)
    out = np.zeros((n, k, 4))
    for i in range(n):
        others = [j for j in range(n) if j != i and valid[j]]
        d2 = np.array([np.sum((p[j] - p[i]) ** 2) for j in others])
        order = np.argsort(d2, kind="stable")[:k]
        for slot in range(k):
            if slot < len(order):
                offset = p[others[order[slot]]] - p[i]
            else:  # fewer real neighbours than k: the slot holds a far dummy
                offset = np.full(3, FAR) - p[i]
            out[i, slot, :3] = np.clip(offset * OFFSET_SCALE, -2 * OFFSET_SCALE,
                                       2 * OFFSET_SCALE)
            out[i, slot, 3] = min(np.sum(offset**2) * OFFSET_SCALE**2, 4 * OFFSET_SCALE**2)
    return out.reshape(n, 4 * k)


@pytest.mark.parametrize(("n", "k", "padding"), [(9, 4, 0), (12, 5, 4), (3, 6, 0), (5, 6, 2)])
def test_neighbour_offsets_are_the_nearest_real_vertices(n, k, padding):
    rng = np.random.default_rng(n * 10 + k)
    p = rng.uniform(-1, 1, (2, n + padding, 3)).astype(np.float32)
    valid = np.zeros((2, n + padding), bool)
    valid[:, :n] = True
    got = neighbour_offsets(torch.from_numpy(p), torch.from_numpy(valid), k).numpy()
    assert got.shape == (2, n + padding, 4 * k)
    for b in range(2):
        want = _reference_neighbours(p[b].astype(np.float64), valid[b], k)
        assert np.allclose(got[b, :n], want[:n], atol=1e-4)


def test_offset_moments_are_the_weighted_mean_and_second_moment_of_offsets():
    rng = np.random.default_rng(0)
    b, h, n = 2, 3, 7
    p = rng.uniform(-1, 1, (b, n, 3))
    w = rng.random((b, h, n, n))
    w /= w.sum(-1, keepdims=True)
    got = offset_moments(torch.from_numpy(w), torch.from_numpy(p)).numpy()
    assert got.shape == (b, n, MOMENT_CHANNELS * h)
    upper = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    for bi in range(b):
        for i in range(n):
            for hi in range(h):
                offsets = p[bi] - p[bi, i]  # (N, 3)
                mean = w[bi, hi, i] @ offsets
                second = np.einsum("j,ja,jb->ab", w[bi, hi, i], offsets, offsets)
                want = np.concatenate([mean * OFFSET_SCALE,
                                       [second[a, c] * OFFSET_SCALE**2 for a, c in upper]])
                chunk = got[bi, i, hi * MOMENT_CHANNELS : (hi + 1) * MOMENT_CHANNELS]
                assert np.allclose(chunk, want, atol=1e-9)


def test_the_features_do_not_depend_on_where_the_shape_is():
    """Relative features: translating every vertex changes nothing."""
    rng = np.random.default_rng(1)
    p = torch.from_numpy(rng.uniform(-0.5, 0.5, (1, 10, 3)))
    valid = torch.ones(1, 10, dtype=torch.bool)
    shift = torch.tensor([0.3, -0.2, 0.1], dtype=p.dtype)
    a = neighbour_offsets(p, valid, 4)
    c = neighbour_offsets(p + shift, valid, 4)
    assert torch.allclose(a, c, atol=1e-5)
    w = torch.softmax(torch.from_numpy(rng.normal(size=(1, 2, 10, 10))), -1)
    assert torch.allclose(offset_moments(w, p), offset_moments(w, p + shift), atol=1e-9)
