"""The one check of a point cloud before generation, shared by the service and the CLI.

:func:`validate_cloud` applies the point-count limits and the geometry checks;
``spacemesh generate`` and the service (``POST /generate``, gRPC ``Generate``) both call
it, so the same input is refused by both. A refusal is a :class:`CloudError` whose
``kind`` is stable (one of :data:`ERROR_KINDS`): the service answers it as the
problem+json type of that name (413 for ``too-many-points``, 422 for the others), the
CLI as one line on stderr and exit code 2.
"""

from __future__ import annotations

import numpy as np

from spacemesh.errors import KindedError
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


__all__ = ["DEFAULT_MAX_POINTS", "DEFAULT_MIN_POINTS", "DEGENERACY_TOLERANCE", "ERROR_KINDS",
           "CloudError", "check_degenerate", "validate_cloud"]
