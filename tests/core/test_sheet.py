"""Flat sheets of points and the slab they are decoded as (spacemesh.geometry.sheet)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from spacemesh.examples import icosphere
from spacemesh.geometry.sheet import FLAT_SHEET, SLAB_THICKNESS, sheet_plane, slab_points
from spacemesh.primitives import sample_surface


def _rotation(seed: int) -> np.ndarray:
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.floats(1e-3, 1e3), count=st.integers(3, 500))
def test_a_plane_in_any_frame_is_a_sheet_and_its_copy_lies_behind(seed, scale, count):
    rng = np.random.default_rng(seed)
    rotation = _rotation(seed)
    flat = np.c_[rng.uniform(-1, 1, (count, 2)), np.zeros(count)]  # (P, 3) on z = 0
    points = scale * flat @ rotation.T + rng.normal(size=3)
    normal, flatness = sheet_plane(points)
    assert flatness < 1e-6
    assert abs(abs(normal @ rotation[:, 2]) - 1.0) < 1e-6
    facing = rotation[:, 2]  # seen from +z of the sheet's own frame
    slab = slab_points(points, facing)
    assert slab is not None and slab.shape == (2 * count, 3)
    np.testing.assert_array_equal(slab[:count], points)
    behind = (slab[count:] - points) @ facing  # (P,) how far each copy went, signed
    diagonal = np.linalg.norm(np.ptp(points, axis=0))
    np.testing.assert_allclose(behind, -SLAB_THICKNESS * diagonal, rtol=1e-6)
    flipped = slab_points(points, -facing)
    assert flipped is not None
    np.testing.assert_allclose((flipped[count:] - points) @ facing, -behind, rtol=1e-6)


def test_curved_or_thick_clouds_are_not_sheets():
    points, _ = sample_surface(icosphere(3), 1000, np.random.default_rng(0))
    half = points[points[:, 2] > 0]  # a one-sided scan of a sphere: a cap, not a sheet
    assert sheet_plane(half)[1] > FLAT_SHEET and slab_points(half, [0, 0, 1]) is None
    rng = np.random.default_rng(1)
    plate = np.c_[rng.uniform(-1, 1, (400, 2)), rng.uniform(-0.05, 0.05, 400)]
    assert sheet_plane(plate)[1] > FLAT_SHEET and slab_points(plate, [0, 0, 1]) is None
    thin = plate * [1, 1, 0.05]  # 0.14% of the diagonal: a sheet, as a scan's noise
    assert sheet_plane(thin)[1] < FLAT_SHEET and slab_points(thin, [0, 0, 1]) is not None


def test_too_few_or_coincident_points_are_no_sheet():
    assert slab_points(np.zeros((2, 3)), [0, 0, 1]) is None
    assert sheet_plane(np.ones((5, 3)))[1] == 0.0
    assert slab_points(np.ones((5, 3)), [0, 0, 1]) is None
