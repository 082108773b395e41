"""The points as scans give them: outliers set aside, and the noise measured.

Scanned clouds carry stray points (reflections, dust, mixed pixels) and noise. A single
stray point far from the surface is the worst case for the pipeline: farthest-point
sampling picks it first as a vertex, the encoder reads it, and the fit pulls the
surface toward it. :func:`assess_points` finds such points before anything else runs
and measures the noise of the rest; the pipeline makes the mesh from the kept points
and the fit report says how many were set aside (``points_outliers``) and how noisy the
rest are (``points_noise``).

**Outliers** (:func:`find_outliers`). A point is set aside when either

* it is far from its neighbours: the distance to its :data:`SPREAD_NEIGHBOUR`-th
  nearest point is over :data:`SPREAD_FACTOR` times the median of that distance over
  the cloud (isolated points, and points inside sparse clumps of outliers), or
* it is off the surface of its neighbours: a quadric height field fitted to its
  :data:`SURFACE_NEIGHBOURS` nearest points (itself left out, in the frame of their
  plane) passes farther from it than :data:`LIFT_FACTOR` times the larger of the
  neighbours' own spread about that quadric, their median over the cloud, and
  :data:`MIN_LIFT` median point spacings, and its nearest point is more than
  :data:`MIN_GAP` median spacings away. On a surface, a point's neighbours lie on a
  smooth patch that passes through it (up to the noise); a stray point near the surface
  sits above the patch of the surface points around it, and apart from them.

The tests run twice (:data:`OUTLIER_ROUNDS`), the second time on the points the first
kept, so that strays that shielded each other are found too. Both are relative to the
cloud's own spacing and spread, so they do not depend on its units or density. A
point of a crease or corner is rarely set aside: no quadric fits its neighbours, whose
spread is then as large as its own distance. Stray points closer to the surface than
the tests reach stay. On the 27 dev meshes with 2,048 points and 5% of uniform
outliers in the bounding box, the tests set aside 67% of the strays (about 12 per cloud
farther than 2% of the diagonal from the surface stay); on the clean clouds they set
aside 6 of 55,296 points (5 clouds touched), and 0.17% of the points of clouds with 1%
noise.

**Noise** (:func:`estimate_noise`). Around :data:`NOISE_CENTRES` points (a fixed
subset), a quadric height field is fitted to the :data:`NOISE_NEIGHBOURS` nearest
points in the frame of their plane; the residual's standard deviation (with the six
fitted parameters' degrees of freedom taken off) is the noise along the normal there.
The median over the centres is the cloud's noise, as a fraction of its bounding-box
diagonal. The quadric absorbs curvature, so a smooth clean surface gives nearly 0;
creases and corners, which no quadric fits, leave a floor of about 0.1 to 0.5% of
the diagonal on 2,048 points of a CAD part. On the real meshes' dev split with 2,048
points, Gaussian noise of 0.5, 1 and 2% of the diagonal reads 0.5-0.8, 1.0-1.2 and
1.5-2.0%.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.io.reduce import reduction_indices
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Neighbour whose distance measures how isolated a point is.
SPREAD_NEIGHBOUR = 8
#: Set aside beyond this many times the median of that distance.
SPREAD_FACTOR = 3.0
#: Neighbours of each point's surface fit (the point itself left out).
SURFACE_NEIGHBOURS = 24
#: Set aside beyond this many times the neighbours' own spread about their surface ...
LIFT_FACTOR = 3.5
#: ... and beyond that many times this many median nearest-neighbour spacings.
MIN_LIFT = 0.5
#: ... and only when its nearest point is farther than this many median spacings (the
#: tip of a thin part lies off the patch of its neighbours too, but among them).
MIN_GAP = 2.0
#: Rounds of the tests (each on the points the rounds before kept).
OUTLIER_ROUNDS = 2
#: Points whose surfaces are fitted at once (bounds the memory on large clouds).
CHUNK = 16_384
#: Points of a larger cloud that the tests fit patches to (a fixed subset).
CLEANING_POINTS = 20_000
#: Points around which the noise is measured (a fixed subset of larger clouds).
NOISE_CENTRES = 4096
#: Neighbours of each quadric fit of the noise estimate.
NOISE_NEIGHBOURS = 24
#: Seed of the noise estimate's subset (the estimate is deterministic).
CLEANING_SEED = 0
#: Fewest points the tests need; smaller clouds are kept whole, their noise 0.
MIN_CLEANING_POINTS = 32


@dataclass(frozen=True)
class PointsQuality:
    """What :func:`assess_points` found.

    Attributes
    ----------
    kept : (P,) bool
        The points the mesh is made from (not outliers).
    outliers : float
        The share of the points set aside, from 0 to 1.
    noise : float
        The kept points' noise along the surface normal, as a fraction of their
        bounding-box diagonal.
    """

    kept: BoolArray
    outliers: float
    noise: float


def _unit(points: FloatArray) -> tuple[FloatArray, float]:
    """``points`` centred on their bounding box and divided by its diagonal (so that
    the estimates do not depend on units), and that diagonal."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not len(points):
        return points, 0.0
    low, high = points.min(axis=0), points.max(axis=0)
    diagonal = float(np.linalg.norm(high - low))
    return (points - (low + high) / 2) / (diagonal if diagonal > 0 else 1.0), diagonal


def _quadric_fits(points: FloatArray, near: IntArray
                  ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Quadric height fields fitted to the neighbourhoods ``near`` ``(C, k)``, each in
    the frame of its plane (the height along the direction of least variance).

    Returns
    -------
    centroid : (C, 3)
    frame : (C, 3, 3)
        Ascending eigenvectors of the neighbourhood's covariance (column 0: the normal).
    coefficients : (C, 6)
        Of ``h = a x^2 + b x y + c y^2 + d x + e y + f``.
    spread : (C,)
        The neighbours' residual standard deviation about their quadric (the six fitted
        parameters' degrees of freedom taken off).
    """
    patch = points[near]  # (C, k, 3)
    centroid = patch.mean(axis=1)  # (C, 3)
    centred = patch - centroid[:, None]
    frame = np.linalg.eigh(np.einsum("cki,ckj->cij", centred, centred))[1]  # (C, 3, 3)
    design, height = _heights(centred, frame)  # (C, k, 6), (C, k)
    normal_matrix = np.einsum("cki,ckj->cij", design, design)  # (C, 6, 6)
    scale = np.trace(normal_matrix, axis1=1, axis2=2)[:, None, None]
    normal_matrix = normal_matrix + 1e-12 * scale * np.eye(6)
    rhs = np.einsum("cki,ck->ci", design, height)[..., None]  # (C, 6, 1)
    coefficients = np.linalg.solve(normal_matrix, rhs)[..., 0]  # (C, 6)
    residual = height - np.einsum("cki,ci->ck", design, coefficients)  # (C, k)
    dof = max(near.shape[1] - design.shape[2], 1)
    return centroid, frame, coefficients, np.sqrt(np.sum(residual ** 2, axis=1) / dof)


def _heights(centred: FloatArray, frame: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The quadric design ``(C, k, 6)`` and heights ``(C, k)`` of points ``(C, k, 3)``
    given relative to each frame's origin."""
    local = np.einsum("ckd,cde->cke", centred, frame)  # (C, k, 3)
    height, y, x = local[..., 0], local[..., 1], local[..., 2]
    design = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=-1)
    return design, height


@dataclass(frozen=True)
class _Patches:
    """The surface patches of a unit-diagonal cloud: around each of its points, the
    quadric fitted to its :data:`SURFACE_NEIGHBOURS` nearest other points, and the
    thresholds of the two tests.

    Attributes
    ----------
    tree : cKDTree
    spread : (P,) float
        Distance of each point to its :data:`SPREAD_NEIGHBOUR`-th nearest other point.
    gap : (P,) float
        Distance of each point to its nearest other point.
    lift : (P,) float
        Each point's distance from its own patch.
    limit : (P,) float
        The lift beyond which a point near that patch is set aside.
    centroid, frame, coefficients
        The patches (:func:`_quadric_fits`).
    spread_limit : float
        The spread beyond which a point is set aside.
    gap_limit : float
        The gap a point off its patch needs to be set aside.
    """

    tree: cKDTree
    spread: FloatArray
    gap: FloatArray
    lift: FloatArray
    limit: FloatArray
    centroid: FloatArray
    frame: FloatArray
    coefficients: FloatArray
    spread_limit: float
    gap_limit: float

    @classmethod
    def of(cls, points: FloatArray) -> _Patches:
        """The patches of ``points`` ``(P, 3)``, fitted :data:`CHUNK` points at a time."""
        tree = cKDTree(points)
        k = max(SPREAD_NEIGHBOUR, SURFACE_NEIGHBOURS)
        distance, near = tree.query(points, k=k + 1)  # (P, k + 1), self first
        distance, near = distance[:, 1:], near[:, 1:]
        count = len(points)
        lift, own = np.empty(count), np.empty(count)
        centroid, frame = np.empty((count, 3)), np.empty((count, 3, 3))
        coefficients = np.empty((count, 6))
        for start in range(0, count, CHUNK):  # bounded memory on large clouds
            rows = slice(start, start + CHUNK)
            centroid[rows], frame[rows], coefficients[rows], own[rows] = _quadric_fits(
                points, near[rows, :SURFACE_NEIGHBOURS])
            lift[rows] = _lift(points[rows], centroid[rows], frame[rows], coefficients[rows])
        spread = distance[:, SPREAD_NEIGHBOUR - 1]
        spacing = float(np.median(distance[:, 0]))
        floor = max(float(np.median(own)), MIN_LIFT * spacing)
        return cls(tree, spread, distance[:, 0], lift, LIFT_FACTOR * np.maximum(own, floor),
                   centroid, frame, coefficients, SPREAD_FACTOR * float(np.median(spread)),
                   MIN_GAP * spacing)

    def own_outliers(self) -> BoolArray:
        """(P,) the cloud's own points that fail either test."""
        return (self.spread > self.spread_limit) | (
            (self.lift > self.limit) & (self.gap > self.gap_limit))

    def outliers_among(self, others: FloatArray) -> BoolArray:
        """``(Q,)`` which of ``others`` ``(Q, 3)`` (points not in the cloud) fail either
        test, against the patch of their nearest point of the cloud."""
        result = np.empty(len(others), dtype=bool)
        for start in range(0, len(others), CHUNK):
            rows = slice(start, start + CHUNK)
            distance, near = self.tree.query(others[rows], k=SPREAD_NEIGHBOUR)  # (C, k)
            nearest = near[:, 0]
            lift = _lift(others[rows], self.centroid[nearest], self.frame[nearest],
                         self.coefficients[nearest])
            result[rows] = ((distance[:, -1] > self.spread_limit)
                            | ((lift > self.limit[nearest]) & (distance[:, 0] > self.gap_limit)))
        return result


def _lift(points: FloatArray, centroid: FloatArray, frame: FloatArray,
          coefficients: FloatArray) -> FloatArray:
    """``(C,)`` distance along each patch's normal from ``points`` ``(C, 3)`` to the
    patch's quadric."""
    design, height = _heights((points - centroid)[:, None], frame)  # (C, 1, 6), (C, 1)
    return np.abs(height[:, 0] - np.einsum("ci,ci->c", design[:, 0], coefficients))


def find_outliers(points: FloatArray) -> BoolArray:
    """The stray points of a cloud (the module docstring's two tests, in up to
    :data:`OUTLIER_ROUNDS` rounds).

    Clouds of more than :data:`CLEANING_POINTS` points are tested on a fixed subset of
    that many; every other point is then tested against the patch of its nearest kept
    subset point (the same two tests, at the subset's spacing).

    Parameters
    ----------
    points : (P, 3) float
        Finite points.

    Returns
    -------
    (P,) bool
        True for an outlier; all False for clouds of fewer than
        :data:`MIN_CLEANING_POINTS` points.
    """
    points, _ = _unit(points)
    picked = reduction_indices(len(points), CLEANING_POINTS, seed=CLEANING_SEED)
    subset = np.arange(len(points)) if picked is None else picked
    outliers = np.zeros(len(points), dtype=bool)
    patches = None
    for _ in range(OUTLIER_ROUNDS):
        kept = subset[~outliers[subset]]
        if len(kept) < MIN_CLEANING_POINTS:
            return outliers
        patches = _Patches.of(points[kept])
        found = patches.own_outliers()
        if not found.any():
            break
        outliers[kept[found]] = True
        patches = None
    if len(subset) < len(points):
        kept = subset[~outliers[subset]]
        if patches is None and len(kept) >= MIN_CLEANING_POINTS:
            patches = _Patches.of(points[kept])
        if patches is not None:
            others = np.ones(len(points), dtype=bool)
            others[subset] = False
            outliers[others] = patches.outliers_among(points[others])
    return outliers


def estimate_noise(points: FloatArray) -> float:
    """The cloud's noise along the surface normal, as a fraction of its bounding-box
    diagonal (the module docstring).

    Parameters
    ----------
    points : (P, 3) float
        Finite points, outliers already set aside.

    Returns
    -------
    float
        0 for clouds of fewer than :data:`MIN_CLEANING_POINTS` points.
    """
    points, diagonal = _unit(points)
    if len(points) < MIN_CLEANING_POINTS or diagonal <= 0:
        return 0.0
    pick = reduction_indices(len(points), NOISE_CENTRES, seed=CLEANING_SEED)
    centres = points if pick is None else points[pick]
    k = min(NOISE_NEIGHBOURS, len(points) - 1)
    _, near = cKDTree(points).query(centres, k=k + 1)  # (C, k + 1), the centre included
    return float(np.median(_quadric_fits(points, near)[3]))  # unit diagonal


def assess_points(points: FloatArray) -> PointsQuality:
    """Set the outliers aside and measure the noise of the rest.

    Parameters
    ----------
    points : (P, 3) float
        Finite points.

    Returns
    -------
    PointsQuality
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    outliers = find_outliers(points)
    kept = ~outliers
    share = float(outliers.mean()) if len(points) else 0.0
    return PointsQuality(kept=kept, outliers=share, noise=estimate_noise(points[kept]))


__all__ = ["PointsQuality", "assess_points", "estimate_noise", "find_outliers"]
