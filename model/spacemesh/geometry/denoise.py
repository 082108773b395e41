"""Noisy points moved onto the surface they sample, before the pipeline uses them.

Scanned points scatter about their surface. The encoder reads the scatter, the vertex
starts pick points off the surface, and the fit pulls the mesh toward every point, so a
mesh made from noisy points is rougher and farther from the object than one made from
clean points. :func:`denoise_points` moves each point onto a smooth patch of its
neighbours (jet smoothing, Cazals and Pouget 2005): the quadric height field fitted to
its :data:`DENOISE_NEIGHBOURS` nearest points (itself included, in the frame of their
plane; :func:`spacemesh.geometry.cleaning.quadric_fits`, the fits of the outlier tests
and the noise estimate) gives the height the point should have, and the point moves
along the patch's normal to it. :data:`DENOISE_PASSES` passes run, each on the points
the last one moved. Clouds of more than :data:`DENOISE_POINTS` points have their
quadrics fitted on a fixed subset of that many, and every point moves onto the quadric
of its nearest subset point (on 200,000 points, 15 s of fits become 4).

The quadric absorbs curvature, so a smooth surface keeps its shape. A crease or corner
is what no quadric fits: there the patch rounds the edge off, so no point moves farther
than :data:`MAX_MOVE` times the measured noise in all; a crease is then rounded by at
most about the noise, which had blurred it as much.

Only measurably noisy points move, and the points are otherwise returned as they are
(the same array, so a clean cloud's mesh is the same to the byte). Two tests must both
say noise:

* the cloud's noise (:func:`spacemesh.geometry.cleaning.estimate_noise`) is at least
  :data:`DENOISE_NOISE` of the bounding-box diagonal (clean parts read up to about 0.5%
  from their creases, a few up to 1.5%), and
* the points' *scattered* noise (:func:`scattered_noise`) is at least
  :data:`SCATTER_NOISE`: the part of the points' offsets from their quadrics that their
  nearest neighbours do not share. Noise offsets neighbours independently; where the
  quadrics miss the surface itself (a crease, the two sheets of a thin plate in one
  neighbourhood, which the noise estimate reads as noise) neighbours are offset alike.
  Projecting the two sheets of a thin plate would flatten them into one.

On the 27 dev meshes with 2,048 points, the clean clouds read a scattered noise of at
most 0.36% of the diagonal (the thin plate, whose noise estimate is 1.5%), clouds with
0.5, 1 and 2% of Gaussian noise 0.40-0.55, 0.46-0.77 and 0.52-0.98%: no clean cloud is
moved, every cloud with 1% of noise is, and the points' mean distance to the true surface
drops from 0.76 to 0.47% of the diagonal at 1% of noise and from 1.45 to 0.76% at 2%
(``experiments/denoise_sweep.py``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.geometry.cleaning import (
    CHUNK,
    CLEANING_POINTS,
    CLEANING_SEED,
    MIN_CLEANING_POINTS,
    quadric_fits,
    quadric_offsets,
    unit_points,
)
from spacemesh.io.reduce import reduction_indices
from spacemesh.typed import FloatArray, IntArray

#: Noise (a fraction of the bounding-box diagonal, :func:`estimate_noise`) from which the
#: points may be moved.
DENOISE_NOISE = 0.007
#: Scattered noise (:func:`scattered_noise`, a fraction of the diagonal) from which they
#: are moved.
SCATTER_NOISE = 0.004
#: Neighbours of each point's quadric (the point itself included).
DENOISE_NEIGHBOURS = 24
#: Passes of the projection, each on the points the last one moved.
DENOISE_PASSES = 2
#: A point moves at most this many times the measured noise, over all passes.
MAX_MOVE = 3.0
#: Points of a larger cloud whose quadrics are fitted (a fixed subset); every point
#: moves onto the quadric of its nearest subset point.
DENOISE_POINTS = CLEANING_POINTS
#: Width of the neighbours' weights in the refits, in scattered noises (0: no refits).
MODE_WIDTH = 2.0
#: Refits of each quadric with its neighbours weighted.
MODE_ROUNDS = 2
#: Median of the square of a standard normal variable.
_CHI2_MEDIAN = 0.4549


def _offsets(unit: FloatArray, subset: IntArray, neighbours: int, width: float = 0.0,
             rounds: int = 0) -> tuple[FloatArray, FloatArray, IntArray]:
    """Each point's signed height ``(P,)`` above the quadric of the ``neighbours`` points
    of ``subset`` ``(S,)`` nearest to its nearest subset point, that quadric's normal
    ``(P, 3)``, and each subset point's nearest other subset point ``(S,)`` (indices
    into ``subset``); fitted :data:`CHUNK` at a time.

    With ``width`` > 0 each quadric is then refitted ``rounds`` times with the neighbours
    weighted by a Gaussian of ``width`` over their heights above it, first above it
    lifted through the patch's own point: a neighbourhood that holds two sheets of a thin
    part, or two faces of a crease, is fitted to the one its point lies on.
    """
    tree = cKDTree(unit[subset])
    k = min(max(neighbours, 2), len(subset))
    _, near = tree.query(unit[subset], k=k)  # (S, k), into subset, the point itself first
    owner = np.empty(len(unit), dtype=np.int64)  # (P,) into subset
    if len(subset) < len(unit):
        owner[:] = tree.query(unit, k=1)[1]
    owner[subset] = np.arange(len(subset))
    offset, normal = np.empty(len(unit)), np.empty((len(unit), 3))
    for first in range(0, len(subset), CHUNK):  # bounded memory on large clouds
        rows = slice(first, first + CHUNK)
        centroid, frame, coefficients, _ = quadric_fits(unit[subset], near[rows])
        for round_ in range(rounds if width > 0 else 0):
            height = quadric_offsets(unit[subset][near[rows]], centroid, frame,
                                     coefficients)  # (C, k), the patch's own point first
            if round_ == 0:
                height = height - height[:, :1]
            weights = np.exp(-0.5 * (height / width) ** 2)  # (C, k)
            centroid, frame, coefficients, _ = quadric_fits(unit[subset], near[rows], weights)
        mine = np.flatnonzero((owner >= first) & (owner < first + len(centroid)))  # (C',)
        patch = owner[mine] - first
        offset[mine] = quadric_offsets(unit[mine, None], centroid[patch], frame[patch],
                                       coefficients[patch])[:, 0]
        normal[mine] = frame[patch, :, 0]
    return offset, normal, near[:, 1]


def scattered_noise(offset: FloatArray, normal: FloatArray, near: IntArray) -> float:
    """The part of the points' offsets from their patches that nearest neighbours do not
    share, as a standard deviation (in the offsets' unit).

    On a surface sampled with noise the offsets are independent, and the difference of
    two neighbours' offsets is twice as variable as one; where the quadrics miss the
    surface itself (a crease, two sheets of a thin part in one neighbourhood) nearest
    neighbours are offset alike and the difference is small.

    Parameters
    ----------
    offset : (P,) float
    normal : (P, 3) float
    near : (P,) int
        Each point's nearest other point.
    """
    difference = offset - np.einsum("pi,pi->p", offset[near, None] * normal[near], normal)
    return float(np.sqrt(np.median(difference ** 2) / (2 * _CHI2_MEDIAN)))


def denoise_points(points: FloatArray, noise: float, *,
                   neighbours: int = DENOISE_NEIGHBOURS, passes: int = DENOISE_PASSES,
                   max_move: float = MAX_MOVE, width: float = MODE_WIDTH,
                   mode_rounds: int = MODE_ROUNDS,
                   threshold: float = DENOISE_NOISE, scatter: float = SCATTER_NOISE
                   ) -> FloatArray:
    """Each point moved along its patch's normal onto the quadric of its neighbours
    (the module docstring).

    Parameters
    ----------
    points : (P, 3) float
        Finite points, outliers already set aside.
    noise : float
        Their noise as a fraction of their bounding-box diagonal
        (:func:`spacemesh.geometry.cleaning.estimate_noise`).
    neighbours, passes, max_move, threshold, scatter
        :data:`DENOISE_NEIGHBOURS`, :data:`DENOISE_PASSES`, :data:`MAX_MOVE`,
        :data:`DENOISE_NOISE` and :data:`SCATTER_NOISE`
        (given only by experiments).

    Returns
    -------
    (P, 3) float64
        ``points`` themselves (not a copy) when they are not noisy enough or the cloud
        has fewer than :data:`MIN_CLEANING_POINTS` points; otherwise the moved points.
    """
    if not noise >= threshold or len(points) < MIN_CLEANING_POINTS or passes < 1:
        return points
    unit, diagonal = unit_points(points)  # (P, 3)
    if diagonal <= 0:
        return points
    start = unit
    pick = reduction_indices(len(unit), DENOISE_POINTS, seed=CLEANING_SEED)
    subset = np.arange(len(unit)) if pick is None else pick  # (S,) ascending
    limit = max_move * noise  # unit diagonal
    for round_ in range(passes):
        offset, normal, nearest = _offsets(unit, subset, neighbours)
        if round_ == 0:
            scattered = scattered_noise(offset[subset], normal[subset], nearest)
            if scattered < scatter:
                return points  # the offsets are the surface's own (creases, thin parts)
        if width > 0:
            offset, normal, nearest = _offsets(unit, subset, neighbours, width * scattered,
                                               mode_rounds)
        step = unit - offset[:, None] * normal - start  # (P, 3)
        length = np.linalg.norm(step, axis=1, keepdims=True)
        unit = start + step * np.minimum(1.0, limit / np.maximum(length, 1e-300))
    return np.asarray(points, dtype=np.float64) + (unit - start) * diagonal


__all__ = ["DENOISE_NEIGHBOURS", "DENOISE_NOISE", "DENOISE_PASSES", "DENOISE_POINTS",
           "MAX_MOVE", "SCATTER_NOISE", "denoise_points", "scattered_noise"]
