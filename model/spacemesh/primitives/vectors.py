"""Row-wise vector products for many small arrays.

``np.cross`` moves axes and checks shapes on every call, which costs more than the
product itself on the few rows a local mesh operation handles (an edge collapse's fan, a
pair test): :func:`cross_rows` is the same product on ``(M, 3)`` rows without that.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray


def cross_rows(u: FloatArray, v: FloatArray) -> FloatArray:
    """``np.cross(u, v)`` of ``(M, 3)`` rows.

    Parameters
    ----------
    u, v : (M, 3) float

    Returns
    -------
    (M, 3) float
    """
    u0, u1, u2 = u[:, 0], u[:, 1], u[:, 2]
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0], axis=1)


def triangle_normals(corners: FloatArray) -> FloatArray:
    """Unnormalised normals ``(M, 3)`` (twice the areas long) of triangles ``(M, 3, 3)``."""
    return cross_rows(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def bounding_spheres(corners: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Centroids ``(M, 3)`` of triangles ``corners`` ``(M, 3, 3)`` and the largest
    distance from each to its corners ``(M,)``: a sphere about each triangle."""
    centre = corners.mean(axis=1)
    return centre, np.linalg.norm(corners - centre[:, None], axis=2).max(axis=1)


def unit_rows(rows: FloatArray) -> FloatArray:
    """``rows`` ``(M, 3)`` over their lengths (zero rows stay zero)."""
    return rows / np.maximum(np.linalg.norm(rows, axis=1, keepdims=True), 1e-300)


__all__ = ["bounding_spheres", "cross_rows", "triangle_normals", "unit_rows"]
