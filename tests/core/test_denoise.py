"""Noisy points moved onto their neighbours' surface (spacemesh.geometry.denoise)."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.geometry.cleaning import assess_points
from spacemesh.geometry.denoise import DENOISE_POINTS, MAX_MOVE, denoise_points
from spacemesh.primitives import sample_surface


def _cloud(mesh, count: int = 2048, seed: int = 0) -> np.ndarray:
    points, _ = sample_surface(mesh, count, np.random.default_rng(seed))
    return points


def _diagonal(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.ptp(points, axis=0)))


def _noisy(points: np.ndarray, noise: float, seed: int = 1) -> np.ndarray:
    scale = noise * _diagonal(points)
    return points + np.random.default_rng(seed).normal(scale=scale, size=points.shape)


def _off_cube(points: np.ndarray, cube: np.ndarray) -> np.ndarray:
    """(P,) distance of points near the box of ``cube``'s points from its surface."""
    low, high = cube.min(axis=0), cube.max(axis=0)
    excess = np.abs(points - (low + high) / 2) - (high - low) / 2  # (P, 3)
    outside = np.linalg.norm(np.maximum(excess, 0.0), axis=1)
    return np.abs(outside + np.minimum(excess.max(axis=1), 0.0))


@pytest.mark.parametrize("noise", [0.01, 0.02])
def test_a_noisy_spheres_points_end_closer_to_the_sphere(noise):
    sphere = _cloud(icosphere(5))
    radius = float(np.linalg.norm(sphere, axis=1).mean())
    points = _noisy(sphere, noise)
    quality = assess_points(points)
    points = points[quality.kept]
    moved = denoise_points(points, quality.noise)
    before = np.abs(np.linalg.norm(points, axis=1) - radius).mean()
    after = np.abs(np.linalg.norm(moved, axis=1) - radius).mean()
    assert after < 0.6 * before
    shrink = abs(np.linalg.norm(moved, axis=1).mean() - radius)
    assert shrink < 0.2 * noise * _diagonal(sphere)  # a fifth of the noise at most


@pytest.mark.parametrize("mesh", [icosphere(3), cube_quads(), torus_grid(24, 12)],
                         ids=["sphere", "cube", "torus"])
def test_clean_clouds_are_left_as_they_are(mesh):
    points = _cloud(mesh)
    quality = assess_points(points)
    assert denoise_points(points, quality.noise) is points


def test_a_thin_plate_read_as_noisy_is_left_as_it_is():
    # two clean sheets 1% of the diagonal apart: the noise estimate reads them as noise
    rng = np.random.default_rng(4)
    sheet = np.column_stack([rng.uniform(-1, 1, (2048, 2)), np.zeros(2048)])
    sheet[1024:, 2] = 0.01 * _diagonal(sheet)
    quality = assess_points(sheet)
    assert quality.noise > 0.004
    assert denoise_points(sheet, quality.noise, threshold=0.0) is sheet


def test_a_noisy_cubes_creases_are_not_rounded_off():
    cube = _cloud(cube_quads(), 4096)
    diagonal = _diagonal(cube)
    points = _noisy(cube, 0.01)
    quality = assess_points(points)
    points, cube = points[quality.kept], cube[quality.kept]
    moved = denoise_points(points, quality.noise)
    # points within 3% of the diagonal of an edge end no farther from the surface
    from_faces = np.sort(np.abs(cube - cube.mean(axis=0)), axis=1)  # (P, 3)
    low, high = cube.min(axis=0), cube.max(axis=0)
    edge = (float((high - low).max()) / 2 - from_faces[:, 1]) < 0.03 * diagonal
    assert edge.sum() > 100
    assert _off_cube(moved, cube)[edge].mean() < 0.9 * _off_cube(points, cube)[edge].mean()
    assert _off_cube(moved, cube).mean() < 0.6 * _off_cube(points, cube).mean()
    # and no point moves farther than the bound
    step = np.linalg.norm(moved - points, axis=1)
    assert step.max() <= MAX_MOVE * quality.noise * _diagonal(points) * (1 + 1e-9)


def test_a_large_clouds_points_move_onto_their_subset_quadrics():
    sphere = _cloud(icosphere(4), DENOISE_POINTS + 5000)
    radius = float(np.linalg.norm(sphere, axis=1).mean())
    points = _noisy(sphere, 0.01)
    moved = denoise_points(points, 0.01, threshold=0.0, scatter=0.0)  # forced
    before = np.abs(np.linalg.norm(points, axis=1) - radius)
    after = np.abs(np.linalg.norm(moved, axis=1) - radius)
    assert after.mean() < 0.6 * before.mean()
