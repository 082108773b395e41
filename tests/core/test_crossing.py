"""Crossing quad diagonals: found, dropped weakest first, other 4-cliques kept."""

from __future__ import annotations

import numpy as np

from spacemesh.decode.crossing import quad_diagonal_pairs, segments_cross, uncrossed

SQUARE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.02], [0, 1, 0]], dtype=np.float64)
SIDES_AND_DIAGONALS = np.array([[0, 1], [1, 2], [2, 3], [0, 3], [0, 2], [1, 3]])


def test_both_diagonals_of_a_flat_quad_cross_and_the_weaker_goes():
    pairs = quad_diagonal_pairs(SIDES_AND_DIAGONALS, 4)
    # the three pairings of a 4-clique's opposite edges
    assert sorted(map(tuple, pairs.tolist())) == [(0, 2), (1, 3), (4, 5)]
    crossing = segments_cross(SQUARE, SIDES_AND_DIAGONALS[pairs[:, 0]],
                              SIDES_AND_DIAGONALS[pairs[:, 1]])
    assert crossing.tolist() == [tuple(p) == (4, 5) for p in pairs.tolist()]
    for weak, strong in ((4, 5), (5, 4)):
        weakness = np.zeros(6)
        weakness[weak], weakness[strong] = 2.0, 1.0
        keep = uncrossed(SQUARE, SIDES_AND_DIAGONALS, weakness)
        assert np.flatnonzero(~keep).tolist() == [weak]


def test_a_degree_three_fan_and_a_tetrahedron_are_kept():
    # apex above the centre of a triangle: a 4-clique whose opposite edges do not cross
    fan = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.9, 0], [0.5, 0.3, 0.05]])
    tetra = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.9, 0], [0.5, 0.3, 0.8]])
    clique = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    for positions in (fan, tetra):
        assert len(quad_diagonal_pairs(clique, 4)) == 3
        assert uncrossed(positions, clique, np.arange(6.0)).all()


def test_far_skew_and_parallel_segments_do_not_cross():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0.5, -0.5, 1.0], [0.5, 0.5, 1.0],
                          [0, 1, 0], [1, 1, 0]], dtype=np.float64)
    first = np.array([[0, 1], [0, 1]])
    second = np.array([[2, 3], [4, 5]])  # one skew a full length above, one parallel
    assert not segments_cross(positions, first, second).any()
    assert segments_cross(positions, first, second, max_gap=1.5).tolist() == [True, False]
