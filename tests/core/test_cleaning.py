"""Outliers set aside and noise measured (spacemesh.geometry.cleaning)."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.geometry.cleaning import (
    MIN_CLEANING_POINTS,
    assess_points,
    estimate_noise,
    find_outliers,
)
from spacemesh.primitives import sample_surface


def _cloud(mesh, count: int = 2048, seed: int = 0) -> np.ndarray:
    points, _ = sample_surface(mesh, count, np.random.default_rng(seed))
    return points


def _diagonal(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.ptp(points, axis=0)))


@pytest.mark.parametrize("mesh", [icosphere(3), cube_quads(), torus_grid(24, 12)],
                         ids=["sphere", "cube", "torus"])
def test_clean_surfaces_keep_nearly_every_point(mesh):
    points = _cloud(mesh)
    assert find_outliers(points).mean() <= 0.005  # corners and creases are kept


@pytest.mark.parametrize("mesh", [icosphere(3), cube_quads(), torus_grid(24, 12)],
                         ids=["sphere", "cube", "torus"])
def test_far_stray_points_are_set_aside(mesh):
    points = _cloud(mesh)
    rng = np.random.default_rng(1)
    low, high = points.min(axis=0), points.max(axis=0)
    stray = rng.uniform(low - 0.5 * (high - low), high + 0.5 * (high - low), size=(100, 3))
    # the ones well off the surface: farther than 15% of the diagonal from every point
    far = np.min(np.linalg.norm(stray[:, None] - points[None], axis=2), axis=1) > (
        0.15 * _diagonal(points))
    flagged = find_outliers(np.concatenate([points, stray]))
    assert flagged[len(points):][far].all()
    assert flagged[:len(points)].mean() <= 0.01


def test_a_point_lifted_off_a_plane_is_set_aside_and_its_neighbours_kept():
    rng = np.random.default_rng(2)
    plane = np.column_stack([rng.uniform(-1, 1, (2000, 2)), np.zeros(2000)])  # (P, 3)
    lifted = np.array([[0.0, 0.0, 0.15]])
    flagged = find_outliers(np.concatenate([plane, lifted]))
    assert flagged[-1]
    assert not flagged[:-1].any()


def test_small_clouds_are_kept_whole():
    points = np.random.default_rng(3).normal(size=(MIN_CLEANING_POINTS - 1, 3))
    assert not find_outliers(points).any()
    assert estimate_noise(points) == 0.0


@pytest.mark.parametrize("sigma", [0.005, 0.01, 0.02])
def test_the_noise_estimate_follows_gaussian_noise_on_a_smooth_surface(sigma):
    points = _cloud(icosphere(4), 4096)
    clean = estimate_noise(points)
    noisy = points + np.random.default_rng(4).normal(scale=sigma * _diagonal(points),
                                                     size=points.shape)
    estimate = estimate_noise(noisy)
    assert clean < 0.001  # a quadric absorbs the curvature
    assert 0.6 * sigma <= estimate <= 1.3 * sigma


def test_the_estimates_do_not_depend_on_units_or_order():
    points = _cloud(torus_grid(24, 12))
    points = points + np.random.default_rng(5).normal(scale=0.01, size=points.shape)
    base = assess_points(points)
    scaled = assess_points(points * 1000.0 + 7.0)
    assert scaled.noise == pytest.approx(base.noise, rel=1e-6)
    np.testing.assert_array_equal(scaled.kept, base.kept)
    order = np.random.default_rng(6).permutation(len(points))
    shuffled = assess_points(points[order])
    np.testing.assert_array_equal(shuffled.kept, base.kept[order])


def test_assess_points_reports_the_share_set_aside():
    points = _cloud(icosphere(3))
    stray = np.array([[5.0, 5.0, 5.0], [-5.0, 4.0, 0.0], [0.0, -6.0, 3.0]])
    quality = assess_points(np.concatenate([points, stray]))
    assert quality.kept[-3:].sum() == 0
    assert quality.outliers == pytest.approx((~quality.kept).mean())
    assert quality.noise < 0.002


def test_a_large_cloud_is_tested_on_a_subset_and_every_point_is_judged():
    from spacemesh.geometry.cleaning import CLEANING_POINTS

    points = _cloud(torus_grid(48, 24), CLEANING_POINTS + 10_000, seed=7)
    rng = np.random.default_rng(8)
    low, high = points.min(axis=0), points.max(axis=0)
    stray = rng.uniform(low, high, size=(500, 3))
    far = np.array([np.min(np.linalg.norm(points - s, axis=1)) for s in stray]) > (
        0.05 * _diagonal(points))
    flagged = find_outliers(np.concatenate([points, stray]))
    assert flagged[len(points):][far].mean() >= 0.95  # judged though most are not in the subset
    assert flagged[:len(points)].mean() <= 0.002
