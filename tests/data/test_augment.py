"""Realistic conditioning clouds (spacemesh.data.augment): seeded, well-formed, and safe on
small clouds; in batches the ground truth stays the clean mesh."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.data.augment import PRESETS, AugmentConfig, augment_cloud, get_augment


def _sphere(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    d = np.random.default_rng(seed).normal(size=(count, 3))
    n = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    return n.copy(), n


REALISTIC = get_augment("realistic")
EVERYTHING = AugmentConfig(noise=0.05, outliers=0.2, density=1.0, cap=1.0, scan=1.0)


@pytest.mark.parametrize("config", [REALISTIC, EVERYTHING], ids=["realistic", "everything"])
def test_the_same_seed_gives_the_same_cloud_and_another_seed_another(config):
    points, normals = _sphere(2048)
    a = augment_cloud(points, normals, config, np.random.default_rng(5), 512)
    b = augment_cloud(points, normals, config, np.random.default_rng(5), 512)
    c = augment_cloud(points, normals, config, np.random.default_rng(6), 512)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x, y)
    assert not np.array_equal(a[0], c[0])


@pytest.mark.parametrize("count", [64, 512, 4096])
def test_shapes_dtypes_finite_and_unit_normals(count):
    points, normals = _sphere(2048)
    for seed in range(20):
        p, n, kept = augment_cloud(points, normals, EVERYTHING, np.random.default_rng(seed),
                                   count)
        assert p.shape == n.shape == (count, 3)
        assert p.dtype == n.dtype == np.float32
        assert kept.shape == (2048,) and kept.dtype == bool
        assert np.isfinite(p).all() and np.isfinite(n).all()
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)


def test_every_step_changes_the_cloud_as_described():
    points, normals = _sphere(4096)
    rng = np.random.default_rng(0)
    # a scan from all sides of a sphere keeps the points facing its viewpoints only
    _, _, kept = augment_cloud(points, normals, AugmentConfig(scan=1.0, scan_views=(1, 1)),
                               rng, 256)
    assert 0.3 < kept.mean() < 0.7  # one viewpoint at distance 3 sees about 1/3 of a sphere
    # a cap removes the points beyond one plane
    _, _, kept = augment_cloud(points, normals, AugmentConfig(cap=1.0, cap_fraction=(0.2, 0.2)),
                               rng, 256)
    assert kept.mean() == pytest.approx(0.8, abs=0.01)
    # noise moves points off the sphere; the identity does not
    p, _, kept = augment_cloud(points, normals, AugmentConfig(), rng, 4096)
    assert kept.all() and np.allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-5)
    radii = [np.linalg.norm(augment_cloud(points, normals, AugmentConfig(noise=0.05), rng,
                                          4096)[0], axis=1) for _ in range(5)]
    assert max(np.abs(r - 1).max() for r in radii) > 0.01
    # outliers land inside the box, mostly off the sphere
    off = [np.abs(np.linalg.norm(augment_cloud(points, normals, AugmentConfig(outliers=0.5),
                                               rng, 4096)[0], axis=1) - 1) > 1e-3
           for _ in range(5)]
    assert max(o.mean() for o in off) > 0.1


def test_drops_that_would_empty_a_small_cloud_fall_back_to_fewer_drops():
    config = AugmentConfig(density=1.0, cap=1.0, cap_fraction=(0.9, 0.9), scan=1.0)
    for total in (1, 3, 10, 40, 200):
        points, normals = _sphere(total)
        for seed in range(10):
            p, _, kept = augment_cloud(points, normals, config, np.random.default_rng(seed), 64)
            assert p.shape == (64, 3) and np.isfinite(p).all()
            assert kept.sum() >= min(total, 32)
    # clouds with no usable normals: the scan sees nothing and is skipped
    points, _ = _sphere(300)
    p, _, kept = augment_cloud(points, np.zeros_like(points), AugmentConfig(scan=1.0),
                               np.random.default_rng(0), 128)
    assert kept.all() and np.isfinite(p).all()
    with pytest.raises(ValueError, match="empty"):
        augment_cloud(np.zeros((0, 3)), np.zeros((0, 3)), REALISTIC, np.random.default_rng(0), 8)


def test_presets_and_validation():
    assert PRESETS["none"].is_identity and not REALISTIC.is_identity
    with pytest.raises(ValueError, match="unknown augmentation 'wild'"):
        get_augment("wild")
    with pytest.raises(ValueError, match="noise"):
        AugmentConfig(noise=-0.1)
    with pytest.raises(ValueError, match="cap_fraction"):
        AugmentConfig(cap_fraction=(0.5, 1.0))
