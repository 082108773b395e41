"""The one way a generation's input is read and checked, shared by the service, the CLI
and batch.

:func:`read_generate_input` reads a file (a cloud, reduced to the working size when it is
bigger, or a mesh's surface sampled) within the read limits and checks it with
:func:`validate_cloud`; ``spacemesh generate`` and ``spacemesh batch`` call it, and the
service (``POST /generate``, gRPC ``Generate``) calls its two steps (the reading in a
parse slot, :func:`validate_cloud` with its settings), so the same input is read, reduced
and refused alike everywhere.

:func:`validate_cloud` applies the point-count limits and the geometry checks. A refusal
is a :class:`CloudError` whose ``kind`` is stable (one of :data:`ERROR_KINDS`): the
service answers it as the problem+json type of that name (413 for ``too-many-points``,
422 for the others), the CLI as one line on stderr and exit code 2.
"""

from __future__ import annotations

import os
from dataclasses import replace
from typing import BinaryIO

import numpy as np

from spacemesh.errors import KindedError
from spacemesh.io.limits import ReadLimits
from spacemesh.io.reduce import DEFAULT_MAX_BINARY_POINTS, DEFAULT_WORKING_POINTS
from spacemesh.io.surface import CloudInput, load_cloud_input
from spacemesh.typed import FloatArray

#: Fewest and most points of a request, unless the caller sets other limits (the
#: service's ``--min-points`` and ``--max-points`` defaults).
DEFAULT_MIN_POINTS = 16
DEFAULT_MAX_POINTS = 200_000
#: Relative size of the smallest singular value (of the centred points, over the largest)
#: below which a cloud counts as flat (and likewise for the middle one: a line).
DEGENERACY_TOLERANCE = 1e-6

#: More points than the limit.
TOO_MANY_POINTS = "too-many-points"
#: Fewer points than the limit.
TOO_FEW_POINTS = "too-few-points"
#: A NaN or infinite coordinate or normal.
NON_FINITE = "non-finite"
#: Normals that are not one per point.
INVALID_NORMALS = "invalid-normals"
#: The model reads normals and the cloud has none.
NORMALS_REQUIRED = "normals-required"
#: Identical, collinear or coplanar points.
DEGENERATE_GEOMETRY = "degenerate-geometry"
#: Every kind a :class:`CloudError` may carry.
ERROR_KINDS: tuple[str, ...] = (TOO_MANY_POINTS, TOO_FEW_POINTS, NON_FINITE, INVALID_NORMALS,
                                NORMALS_REQUIRED, DEGENERATE_GEOMETRY)


class CloudError(KindedError):
    """A point cloud that cannot be turned into a surface as sent: a
    :class:`~spacemesh.errors.KindedError` of a kind of :data:`ERROR_KINDS`, its
    ``details`` the ``limit`` and ``points`` of a count, or the ``singular_values`` of
    degenerate geometry."""

    KINDS = ERROR_KINDS


def check_degenerate(points: FloatArray) -> None:
    """Refuse identical, collinear or coplanar points.

    Parameters
    ----------
    points : (P, 3) float64
        Finite points.

    Raises
    ------
    CloudError
        ``degenerate-geometry``, with the singular values of the centred points.
    """
    centred = points - points.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)  # (min(P, 3),) descending
    if not s[0] > 0:
        shape = "all points are identical"
    elif len(s) < 2 or s[1] <= DEGENERACY_TOLERANCE * s[0]:
        shape = "the points are collinear"
    elif len(s) < 3 or s[2] <= DEGENERACY_TOLERANCE * s[0]:
        shape = "the points are coplanar"
    else:
        return
    raise CloudError(DEGENERATE_GEOMETRY, f"{shape}; a surface needs a 3D point cloud",
                     {"singular_values": [float(v) for v in s]})


def validate_cloud(
    points: FloatArray, normals: FloatArray | None = None, *,
    min_points: int = DEFAULT_MIN_POINTS, max_points: int = DEFAULT_MAX_POINTS,
    needs_normals: bool = False,
) -> tuple[FloatArray, FloatArray | None]:
    """Apply the point-count limits and the geometry checks to a parsed cloud.

    Parameters
    ----------
    points : (P, 3) float64
    normals : (P, 3) float64, optional
    min_points, max_points : int
        Fewest and most points accepted.
    needs_normals : bool
        The model's encoder reads normals.

    Returns
    -------
    points : (P, 3) float64, C-contiguous
    normals : (P, 3) float64 or None

    Raises
    ------
    CloudError
        The first check that fails, in this order: too many points, too few, a
        non-finite coordinate, normals not one per point or not finite, normals
        missing, degenerate geometry.
    """
    count = len(points)
    if count > max_points:
        raise CloudError(TOO_MANY_POINTS, f"{count} points; at most {max_points} are "
                         "accepted", {"limit": max_points, "points": count})
    if count < min_points:
        raise CloudError(TOO_FEW_POINTS, f"{count} points; at least {min_points} are "
                         "needed", {"limit": min_points, "points": count})
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise CloudError(NON_FINITE, f"point {bad} has a NaN or infinite coordinate")
    if normals is not None:
        if normals.shape != points.shape:
            raise CloudError(INVALID_NORMALS,
                             f"{len(normals)} normals for {count} points; give one per point")
        if not np.isfinite(normals).all():
            raise CloudError(NON_FINITE, "the normals have NaN or infinite values")
    if needs_normals and normals is None:
        raise CloudError(NORMALS_REQUIRED, "this model reads normals; give one per point")
    check_degenerate(points)
    return np.ascontiguousarray(points), normals


def read_generate_input(
    source: str | os.PathLike[str] | bytes | BinaryIO, *, n_points: int,
    needs_normals: bool = False, file_type: str | None = None,
    limits: ReadLimits | None = None, working_points: int = DEFAULT_WORKING_POINTS,
    min_points: int = DEFAULT_MIN_POINTS,
) -> CloudInput:
    """Read and check a generation's input: the path every caller of the pipeline shares.

    A point cloud of more than ``working_points`` points is reduced to a seeded random
    subset of that many (:func:`spacemesh.io.reduce.reduce_cloud`); a mesh's surface is
    sampled to ``n_points`` points; then :func:`validate_cloud` checks the points.

    Parameters
    ----------
    source : path, bytes or binary file object
    n_points : int
        Points sampled on a mesh's surface (the model's encoder count).
    needs_normals : bool
        The model's encoder reads normals.
    file_type : str, optional
        Overrides the extension.
    limits : ReadLimits, optional
        Checked while reading (``max_points`` counts the points in the file, before the
        reduction); None: the service's default point limit
        (:data:`~spacemesh.io.reduce.DEFAULT_MAX_BINARY_POINTS`) and no other.
    working_points : int
        The size a bigger cloud is reduced to.
    min_points : int
        Fewest points accepted.

    Returns
    -------
    CloudInput
        Its points C-contiguous and checked; ``count`` set when they were reduced.

    Raises
    ------
    MeshFormatError, TooLargeError, UnsupportedFormatError
        From the readers.
    CloudError
        From :func:`validate_cloud`.
    """
    limits = limits or ReadLimits(max_points=DEFAULT_MAX_BINARY_POINTS)
    cloud = load_cloud_input(source, file_type=file_type, limits=limits, n_points=n_points,
                             keep=working_points)
    max_points = limits.max_points or DEFAULT_MAX_BINARY_POINTS
    points, normals = validate_cloud(cloud.points, cloud.normals, min_points=min_points,
                                     max_points=max_points, needs_normals=needs_normals)
    return replace(cloud, points=points, normals=normals)


__all__ = ["DEFAULT_MAX_POINTS", "DEFAULT_MIN_POINTS", "DEGENERACY_TOLERANCE", "ERROR_KINDS",
           "CloudError", "check_degenerate", "read_generate_input", "validate_cloud"]
