"""Conditioning clouds closer to real use: seeded augmentations of a training shape's points.

Real uploads are not the generator's clean, evenly spread samples: scans have noise,
uneven density, regions the scanner never saw (one-sided scans, a cut-off part) and
stray points. :func:`augment_cloud` turns a shape's clean cloud into such a cloud, drawn
from a :class:`numpy.random.Generator` (the same generator state gives the same cloud).
Only the conditioning points change: the ground-truth mesh the losses compare against
stays the clean one.

The steps, in order (each drawn per shape; see :class:`AugmentConfig`):

1. **missing regions**: with probability ``scan``, a one-sided scan keeps only the
   points whose normal faces at least one of a few random viewpoints (back-face culling,
   without occlusion); with probability ``cap``, the points beyond a random plane (a cap
   holding a random fraction of the cloud) are removed;
2. **uneven density**: points are kept with a probability that falls linearly along a
   random direction, from 1 to ``1 - s`` with ``s`` uniform in ``[0, density]``;
3. the ``count`` conditioning points are chosen from those left
   (:func:`spacemesh.runtime.request.choose_points`, as without augmentation);
4. **noise**: Gaussian noise of a standard deviation uniform in ``[0, noise]`` (the
   ``[-1, 1]`` frame) on every point;
5. **outliers**: a fraction uniform in ``[0, outliers]`` of the points is replaced by
   points uniform in ``[-1, 1]^3`` with random unit normals.

A drop (steps 1 and 2) that would leave fewer than ``min_keep`` of the cloud's points
(or fewer than :data:`MIN_POINTS`) is skipped, so that a small cloud, or an unlucky
draw, falls back to fewer drops instead of an empty cloud.

The presets (:data:`PRESETS`) are what ``TrainConfig.augment`` names: ``none`` (the
shipped recipe: the clean cloud) and ``realistic``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spacemesh.runtime.request import choose_points
from spacemesh.typed import FloatArray

#: A drop never leaves fewer points than this (nor fewer than ``min_keep`` of the cloud).
MIN_POINTS = 32


@dataclass(frozen=True)
class AugmentConfig:
    """How far a conditioning cloud departs from the clean samples.

    Attributes
    ----------
    noise : float
        Largest standard deviation of the Gaussian noise on the points.
    outliers : float
        Largest fraction of the points replaced by uniform outliers.
    density : float
        Largest drop in the keep probability along a random direction (0 to 1).
    cap : float
        Probability of removing a cap (the points beyond a random plane).
    cap_fraction : (float, float)
        Range of the fraction of the cloud a cap removes.
    scan : float
        Probability of a one-sided scan.
    scan_views : (int, int)
        Range of the number of viewpoints of a scan.
    min_keep : float
        A drop that would leave fewer than this fraction of the cloud is skipped.
    """

    noise: float = 0.0
    outliers: float = 0.0
    density: float = 0.0
    cap: float = 0.0
    cap_fraction: tuple[float, float] = (0.05, 0.3)
    scan: float = 0.0
    scan_views: tuple[int, int] = (1, 3)
    min_keep: float = 0.25

    def __post_init__(self) -> None:
        for name in ("noise", "outliers", "density", "cap", "scan", "min_keep"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"augmentation {name} must lie in [0, 1]")
        lo, hi = self.cap_fraction
        if not 0.0 <= lo <= hi < 1.0:
            raise ValueError("augmentation cap_fraction must be 0 <= lo <= hi < 1")
        if not 1 <= self.scan_views[0] <= self.scan_views[1]:
            raise ValueError("augmentation scan_views must be 1 <= lo <= hi")

    @property
    def is_identity(self) -> bool:
        """True when the cloud is left as it is (no random draws are made)."""
        return not (self.noise or self.outliers or self.density or self.cap or self.scan)


#: The named presets of ``TrainConfig.augment``.
PRESETS: dict[str, AugmentConfig] = {
    "none": AugmentConfig(),
    "realistic": AugmentConfig(noise=0.015, outliers=0.03, density=0.9, cap=0.3, scan=0.3),
}


def get_augment(name: str) -> AugmentConfig:
    """The named preset (``none`` or ``realistic``).

    Raises
    ------
    ValueError
        An unknown name.
    """
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(
            f"unknown augmentation {name!r}; choose from {', '.join(PRESETS)}"
        ) from None


def _direction(rng: np.random.Generator, count: int = 1) -> FloatArray:
    d = rng.normal(size=(count, 3))
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def _scan_mask(points: FloatArray, normals: FloatArray, views: int,
               rng: np.random.Generator) -> np.ndarray:
    eyes = 3.0 * _direction(rng, views)  # (K, 3) viewpoints outside the [-1, 1] box
    facing = np.einsum("pc,pkc->pk", normals, eyes[None] - points[:, None])  # (P, K)
    return (facing > 0).any(axis=1)


def _cap_mask(points: FloatArray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    s = points @ _direction(rng)[0]
    return s <= np.quantile(s, 1.0 - fraction)


def _density_mask(points: FloatArray, strength: float, rng: np.random.Generator) -> np.ndarray:
    s = points @ _direction(rng)[0]
    t = (s - s.min()) / max(float(np.ptp(s)), 1e-12)
    return rng.random(len(points)) < 1.0 - strength * t


def augment_cloud(
    points: FloatArray, normals: FloatArray, config: AugmentConfig, rng: np.random.Generator,
    count: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A realistic conditioning cloud of ``count`` points from a shape's clean cloud.

    Parameters
    ----------
    points, normals : (P, 3)
        The clean cloud (``[-1, 1]`` frame) and its unit normals; ``P >= 1``.
    config : AugmentConfig
    rng : numpy.random.Generator
    count : int
        Points returned.

    Returns
    -------
    points, normals : (count, 3) float32
        Finite, normals of unit length.
    kept : (P,) bool
        The clean points the drops left (before the choice of ``count``).

    Raises
    ------
    ValueError
        An empty cloud.
    """
    points = np.asarray(points, np.float32)
    normals = np.asarray(normals, np.float32)
    total = len(points)
    if total == 0:
        raise ValueError("cannot augment an empty point cloud")
    floor = min(total, max(MIN_POINTS, int(np.ceil(config.min_keep * total))))
    kept = np.ones(total, bool)

    def drop(mask: np.ndarray) -> None:
        nonlocal kept
        if (kept & mask).sum() >= floor:
            kept = kept & mask

    if rng.random() < config.scan:
        drop(_scan_mask(points, normals, int(rng.integers(*config.scan_views, endpoint=True)),
                        rng))
    if rng.random() < config.cap:
        drop(_cap_mask(points, float(rng.uniform(*config.cap_fraction)), rng))
    if config.density > 0:
        drop(_density_mask(points, float(rng.uniform(0.0, config.density)), rng))
    left = np.flatnonzero(kept)
    pick = left[choose_points(len(left), count, rng)]
    p, n = points[pick].copy(), normals[pick].copy()
    if config.noise > 0:
        p += rng.normal(scale=rng.uniform(0.0, config.noise), size=p.shape).astype(np.float32)
    if config.outliers > 0:
        m = round(float(rng.uniform(0.0, config.outliers)) * count)
        where = rng.choice(count, m, replace=False)
        p[where] = rng.uniform(-1.0, 1.0, size=(m, 3))
        n[where] = _direction(rng, m)
    return p.astype(np.float32), n.astype(np.float32), kept
