"""Big point clouds: the seeded subset of rows the pipeline works on.

A cloud of more than a working size (:data:`DEFAULT_WORKING_POINTS`) is reduced to that
many of its points, drawn uniformly at random without replacement with a fixed seed
(:data:`REDUCE_SEED`) and kept in the file's order, with the normals of the same rows.
The same file therefore always gives the same points.

Why a uniform random subset rather than a voxel grid or Poisson-disk sampling: it keeps
the cloud's distribution as it is: its density, its noise, and its share of outliers
(the pipeline estimates both, :mod:`spacemesh.geometry.cleaning`). A voxel grid or a
Poisson disk keeps one point per cell, so isolated outliers, each alone in its cell,
would all survive while the surface is thinned: 5% of uniform outliers in 10 million
points become most of a 200,000-point grid. The pipeline only ever reads random subsets
of far fewer points anyway: 2,048 for the encoder, 4,096 for the geometry stage's fit,
20,000 for the fit report; farthest-point sampling, the feature weights and the cleaning
read all the kept points, and their cost grows with them.

The reduction works on the rows as read (any numeric dtype, views over the file's bytes):
only the kept rows are converted to float64, so a reader's peak is the file's bytes plus
an index and a mask per row, not a float64 copy of every row.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray, IntArray

#: Points a cloud is reduced to (a cloud of at most this many is used whole): the old
#: per-request limit, at which the pipeline's stages were sized and measured.
DEFAULT_WORKING_POINTS = 200_000
#: Most points of a binary cloud (binary PLY, NPY, NPZ) the service accepts by default.
DEFAULT_MAX_BINARY_POINTS = 20_000_000
#: Seed of the subset: the same cloud always gives the same points.
REDUCE_SEED = 0


def reduction_indices(count: int, keep: int, *, seed: int = REDUCE_SEED) -> IntArray | None:
    """The rows a cloud of ``count`` points keeps, or None when it keeps them all.

    Parameters
    ----------
    count : int
        Rows of the cloud.
    keep : int
        Most rows kept (at least 1).
    seed : int
        Seed of the draw.

    Returns
    -------
    (keep,) int64, ascending, or None
        Distinct rows drawn uniformly at random; None when ``count <= keep``.

    Raises
    ------
    ValueError
        ``keep`` is below 1.

    Examples
    --------
    >>> reduction_indices(10, 20) is None
    True
    >>> len(reduction_indices(1000, 10))
    10
    """
    if keep < 1:
        raise ValueError(f"keep must be at least 1, not {keep}")
    if count <= keep:
        return None
    picked = np.random.default_rng(seed).choice(count, keep, replace=False)
    return np.sort(picked).astype(np.int64)


def reduce_cloud(points: np.ndarray, normals: np.ndarray | None, keep: int | None, *,
                 seed: int = REDUCE_SEED) -> tuple[FloatArray, FloatArray | None]:
    """A cloud's kept rows as float64, with the normals of the same rows.

    Parameters
    ----------
    points : (N, 3) numeric array
        Any numeric dtype; may be a view over a file's bytes (only the kept rows are
        copied).
    normals : (N, 3) numeric array, optional
    keep : int, optional
        Most rows kept (None: all).
    seed : int
        Seed of the draw (:func:`reduction_indices`).

    Returns
    -------
    points : (M, 3) float64, C-contiguous
        ``M = min(N, keep)``; the rows in their order in the file.
    normals : (M, 3) float64 or None

    Raises
    ------
    ValueError
        ``normals`` is not one row per point.
    """
    if normals is not None and len(normals) != len(points):
        raise ValueError(f"{len(normals)} normals for {len(points)} points")
    rows = None if keep is None else reduction_indices(len(points), keep, seed=seed)
    if rows is None:
        kept, kept_normals = points, normals
    else:
        kept = points[rows]
        kept_normals = None if normals is None else normals[rows]
    return (np.ascontiguousarray(kept, dtype=np.float64),
            None if kept_normals is None else np.ascontiguousarray(kept_normals,
                                                                    dtype=np.float64))


__all__ = ["DEFAULT_MAX_BINARY_POINTS", "DEFAULT_WORKING_POINTS", "REDUCE_SEED",
           "reduce_cloud", "reduction_indices"]
