"""The onnxruntime backend runs one batch item per graph call on one thread: an item's
outputs are the same bits alone, in a batch, and at any worker count (issue 46)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.runtime import ModelRepository
from spacemesh.runtime.repository import DETERMINISTIC_INTRA_OP_THREADS


@pytest.fixture(scope="module")
def batch(shipped):
    """Four encoder inputs and connectivity inputs of the shipped model."""
    spec_points = shipped.backend.encoder.get_inputs()[0].shape[1]
    n_points = spec_points if isinstance(spec_points, int) else 2048
    rng = np.random.default_rng(3)
    points = rng.uniform(-1, 1, (4, n_points, 3)).astype(np.float32)
    vertices = rng.uniform(-1, 1, (4, 120, 3)).astype(np.float32)
    valid = np.ones((4, 120), bool)
    valid[1, 100:] = False
    return points, vertices, valid


def outputs(backend, points, vertices, valid):
    volumes = backend.encode(points)
    emb = backend.connect(vertices, valid, volumes)
    return [*volumes, emb.x, emb.root, emb.prev, emb.next, np.float64(emb.tau)]


def test_sessions_run_on_one_thread(shipped):
    for session in (shipped.backend.encoder, shipped.backend.connectivity):
        options = session.get_session_options()
        assert options.intra_op_num_threads == DETERMINISTIC_INTRA_OP_THREADS == 1


def test_items_are_the_same_bits_alone_in_a_batch_and_at_two_workers(shipped, batch):
    points, vertices, valid = batch
    two = ModelRepository.load(shipped.path, threads=2, golden=False).backend
    assert two.workers == 2 and shipped.backend.workers == 1
    together = outputs(two, points, vertices, valid)
    serial = outputs(shipped.backend, points, vertices, valid)
    for a, b in zip(together, serial, strict=True):
        assert np.array_equal(a, b)
    for b in range(len(points)):  # each item alone
        alone = outputs(shipped.backend, points[b:b + 1], vertices[b:b + 1], valid[b:b + 1])
        for whole, part in zip(together[:-1], alone[:-1], strict=True):
            assert np.array_equal(whole[b:b + 1], part)
