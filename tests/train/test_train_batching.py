"""Batches: padding, dense adjacency, concatenated connectivity, augmentation."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.data.shards import open_dataset  # noqa: E402
from spacemesh.train.batching import (  # noqa: E402
    collate,
    concat_connectivity,
    prepare_sample,
    random_scaling,
)


@pytest.fixture(scope="module")
def samples(toy_data):
    return [prepare_sample(r) for r in open_dataset(toy_data, "train")[:5]]


def test_collate_pads_and_marks_real_vertices(samples):
    batch = collate(samples, n_points=100, normals=True, rng=np.random.default_rng(0))
    n = max(s.n_vertices for s in samples)
    assert batch.points.shape == (5, 100, 6)
    assert batch.positions.shape == (5, n, 3) and batch.adjacency.shape == (5, n, n)
    for i, s in enumerate(samples):
        assert int(batch.valid[i].sum()) == s.n_vertices
        assert bool(batch.valid[i, : s.n_vertices].all())
        adj = batch.adjacency[i].numpy()
        assert (adj == adj.T).all() and not adj.diagonal().any()
        assert adj.sum() == 2 * len(s.connectivity.edges)
    padded = collate(samples, n_points=10, normals=False, pad_to=64, connectivity=False)
    assert padded.positions.shape == (5, 64, 3) and padded.table is None
    with pytest.raises(ValueError):
        collate(samples, n_points=10, normals=False, pad_to=3)


def test_jitter_moves_the_vertices_but_not_the_targets(samples):
    exact = collate(samples, n_points=10, normals=False, rng=np.random.default_rng(3))
    noisy = collate(samples, n_points=10, normals=False, rng=np.random.default_rng(3),
                    jitter=0.02)
    valid = exact.valid.numpy()
    moved = (noisy.positions - exact.positions).numpy()[valid]  # (sum n_i, 3)
    assert 0.015 < moved.std() < 0.025 and np.abs(moved).max() < 0.2
    assert not (noisy.positions.numpy()[~valid]).any()  # padding stays zero
    assert torch.equal(exact.adjacency, noisy.adjacency)
    assert exact.table.rows == noisy.table.rows


def test_concatenated_connectivity_keeps_each_mesh(samples):
    n = 50
    graph = concat_connectivity([s.connectivity for s in samples], n)
    assert graph.n_vertices == 5 * n
    triplets = {tuple(t) for t in graph.next_triplets().tolist()}
    for b, s in enumerate(samples):
        for i, j, k in s.connectivity.next_triplets().tolist():
            assert (i + b * n, j + b * n, k + b * n) in triplets
    assert len(triplets) == sum(len(s.connectivity.neighbours) for s in samples)


def test_table_covers_every_relation(samples):
    batch = collate(samples, n_points=10, normals=False)
    assert batch.table.rows == sum(len(s.connectivity.neighbours) for s in samples)


def test_random_scaling_renormalises():
    rng = np.random.default_rng(0)
    v = rng.uniform(-1, 1, (20, 3)).astype(np.float32)
    p = rng.uniform(-1, 1, (30, 3)).astype(np.float32)
    n = rng.normal(size=(30, 3)).astype(np.float32)
    v2, _p2, n2 = random_scaling(v, p, n, np.array([2.0, 0.5, 1.0]))
    extent = v2.max(0) - v2.min(0)
    assert extent.max() == pytest.approx(2.0, abs=1e-5)
    assert np.allclose((v2.max(0) + v2.min(0)) / 2, 0, atol=1e-5)
    assert np.allclose(np.linalg.norm(n2, axis=1), 1, atol=1e-5)
