"""The angular fallback: geometric cycles, oriented by Phi_bar."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.angular import angular_cycles, oriented_angular_cycles
from spacemesh.encode import encode_connectivity
from spacemesh.examples import EXAMPLES
from spacemesh.matching import single_cycle_mask
from spacemesh.permutation import group_by_degree


def groups(mesh):
    """(vertices, neighbours (B, d), true local successors (B, d)) per degree."""
    conn = encode_connectivity(mesh)
    local = conn.local_successor()
    for d, vertices in group_by_degree(conn.offsets).items():
        slots = conn.offsets[vertices][:, None] + np.arange(d)
        yield vertices, conn.neighbours[slots], local[slots]


def one_hot_log(perms: np.ndarray) -> np.ndarray:
    b, d = perms.shape
    log = np.full((b, d, d), -30.0)
    log[np.arange(b)[:, None], np.arange(d), perms] = 0.0
    return log


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_the_angular_order_is_the_true_one_up_to_direction(name):
    mesh = EXAMPLES[name]()
    for vertices, neighbours, truth in groups(mesh):
        cycles = angular_cycles(mesh.vertices, vertices, neighbours)
        assert single_cycle_mask(cycles).all()
        oriented = oriented_angular_cycles(mesh.vertices, vertices, neighbours,
                                           one_hot_log(truth))
        assert np.array_equal(oriented, truth)


def test_phi_bar_picks_the_direction():
    mesh = EXAMPLES["sphere"]()
    vertices, neighbours, truth = next(groups(mesh))
    reverse = np.empty_like(truth)
    reverse[np.arange(len(truth))[:, None], truth] = np.arange(truth.shape[1])
    got = oriented_angular_cycles(mesh.vertices, vertices, neighbours, one_hot_log(reverse))
    assert np.array_equal(got, reverse)


def test_degenerate_neighbourhoods_still_give_one_cycle():
    positions = np.zeros((6, 3))  # every neighbour at the vertex itself
    cycles = angular_cycles(positions, np.array([0]), np.array([[1, 2, 3, 4, 5]]))
    assert single_cycle_mask(cycles).all()
