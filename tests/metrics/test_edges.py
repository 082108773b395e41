"""Edge points (NDC's rule), ECD and EF1."""

from __future__ import annotations

import numpy as np

from spacemesh.examples import cube_quads, icosphere
from spacemesh.metrics import SurfaceSamples, edge_chamfer_f1, edge_mask, sample_mesh


def cube_samples(count=10_000, seed=0):
    cube = cube_quads(2.0)
    return sample_mesh(cube.with_vertices(cube.vertices - 1.0), count, seed)


def distance_to_cube_edges(points):
    """Distance from points on the surface of [-1, 1]^3 to the nearest of its 12 edges."""
    second = np.sort(np.abs(points), axis=1)[:, 1]  # the larger of the two free coordinates
    return 1.0 - second


def test_cube_edge_points_lie_along_its_twelve_edges():
    samples = cube_samples()
    mask = edge_mask(samples)
    distance = distance_to_cube_edges(samples.points)
    assert 0.03 < mask.mean() < 0.3
    assert distance[mask].max() < 0.2  # a band a few sample spacings wide
    assert mask[distance < 0.01].mean() > 0.95  # and everything right at an edge is in it
    # every edge gets points: the edge is identified by its two extreme coordinates
    edges = {tuple(np.sign(p) * (np.abs(p) > 0.8)) for p in samples.points[mask]}
    assert len({e for e in edges if sum(map(abs, e)) == 2}) == 12


def test_a_sphere_has_almost_no_edge_points():
    assert edge_mask(sample_mesh(icosphere(3), 10_000, 0)).mean() < 0.005


def test_the_literal_mean_rule_misses_right_angles():
    assert edge_mask(cube_samples(), rule="mean").mean() < 0.01


def test_empty_edge_sets_follow_ndc():
    samples = cube_samples(2000)
    edges = samples.subset(edge_mask(samples))
    none = SurfaceSamples(np.zeros((0, 3)), np.zeros((0, 3)))
    assert edge_chamfer_f1(edges, none).chamfer == 0.0  # no edges in the ground truth
    assert edge_chamfer_f1(none, none).f1 == 1.0
    missing = edge_chamfer_f1(none, edges)  # edges missed: measured against the origin
    assert missing.f1 == 0.0 and missing.chamfer > 1.0
    same = edge_chamfer_f1(edges, edges)
    assert same.chamfer == 0.0 and same.f1 == 1.0
