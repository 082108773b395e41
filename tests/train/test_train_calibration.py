"""Threshold calibration on exactly fitted embeddings: the F1 threshold, then the decode's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("torch")

from spacemesh.decode import DecodeOptions
from spacemesh.encode import encode_connectivity
from spacemesh.examples import icosphere
from spacemesh.fitting import EmbeddingFitConfig, fit_mesh
from spacemesh.spacetime import pairwise_distance
from spacemesh.train.batching import Sample
from spacemesh.train.evaluate import (
    DECODE_PAIR_RATIOS,
    calibrate_decode_threshold,
    calibrate_threshold,
    decoded_scores,
)


@pytest.fixture(scope="module")
def fitted():
    mesh = icosphere(2)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=400, threads=1))
    assert result.exact
    empty = np.zeros((1, 3), np.float32)
    sample = Sample("icosphere", mesh.vertices.astype(np.float32), empty, empty,
                    encode_connectivity(mesh))
    return sample, result.embeddings


def _below_weakest_edges(emb, n: int, missing: int) -> float:
    """A threshold that leaves out the ``missing`` weakest true edges."""
    d = np.sort(pairwise_distance(emb.adjacency, distance="spacetime")[np.triu_indices(n, 1)])
    n_edges = int((d < emb.tau).sum())
    return float(0.5 * (d[n_edges - missing - 1] + d[n_edges - missing]))


def test_the_f1_threshold_separates_an_exact_fit(fitted):
    sample, emb = fitted
    low = replace(emb, tau=_below_weakest_edges(emb, sample.n_vertices, 20))
    tau, f1 = calibrate_threshold([sample], [low], DecodeOptions())
    # the candidates are quantiles of the true edges' distances and an edge is d < tau,
    # so the weakest true edge itself sits on the last candidate: at most one is missed
    n_edges = len(sample.connectivity.edges)
    assert f1 >= 2 * (n_edges - 1) / (2 * n_edges - 1) - 1e-12
    assert tau > low.tau
    triangles = DecodeOptions(max_sides=3)  # the cut recovers that one edge
    scores = decoded_scores([sample], [replace(emb, tau=tau)], triangles)
    assert scores["decoded_edge_f1"] == [1.0]


def test_the_decode_threshold_takes_more_pairs_when_that_decodes_better(fitted):
    sample, emb = fitted
    tau = _below_weakest_edges(emb, sample.n_vertices, 20)
    options = DecodeOptions()
    at_tau = decoded_scores([sample], [replace(emb, tau=tau)], options)["next_accuracy"][0]
    assert at_tau < 1.0
    chosen, scores = calibrate_decode_threshold([sample], [emb], options, tau)
    assert scores["ratio"] in DECODE_PAIR_RATIOS and scores["ratio"] > 1.0
    assert chosen > tau and scores["next_accuracy"] > at_tau
    only_one, same = calibrate_decode_threshold([sample], [emb], options, tau, ratios=(1.0,))
    assert only_one == tau and same["next_accuracy"] == at_tau
