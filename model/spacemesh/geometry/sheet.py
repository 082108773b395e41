"""Flat sheets of points, decoded as a thin slab (docs/GEOMETRY.md, "Open surfaces").

The decode makes closed meshes, and a flat sheet of points (a wall, a floor, one face of
a box seen square-on) has no thickness to close: its closed decode is two layers on one
plane that cross everywhere, and once the crossing faces go and the mesh is trimmed to
the points, the sheet comes back in shreds (a 2 x 2 square of 375 points: 8 pieces
covering 2.5 of its 4 units of area). When the points lie on one plane, they get a copy
pushed back behind it (:func:`slab_points`), the slab is decoded closed, and its side
the points face is what the trimming keeps: one piece over the whole square.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray

#: Points within this RMS distance of their best-fit plane, as a fraction of their
#: bounding-box diagonal, form a flat sheet. The flat one-sided scans of the dev and test
#: splits read 0.05% to 0.3%, every other one at least 1% (a thin partition part 1.0%,
#: the others 2.3% and up).
FLAT_SHEET = 0.005

#: How far behind the sheet its copy is pushed, as a fraction of the diagonal.
SLAB_THICKNESS = 0.05


def sheet_plane(points: FloatArray) -> tuple[FloatArray, float]:
    """The best-fit plane of ``points``: its unit normal and the points' RMS distance
    from it over their bounding-box diagonal (0 for fewer than 3 points or a single
    position).

    Parameters
    ----------
    points : (P, 3) float

    Returns
    -------
    normal : (3,) float
    flatness : float
    """
    points = np.asarray(points, dtype=np.float64)
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
    if len(points) < 3 or diagonal == 0.0:
        return np.array([0.0, 0.0, 1.0]), 0.0
    centred = points - points.mean(axis=0)
    values, vectors = np.linalg.eigh(centred.T @ centred / len(points))  # ascending
    return vectors[:, 0], float(np.sqrt(max(values[0], 0.0)) / diagonal)


def slab_points(points: FloatArray, facing: FloatArray) -> FloatArray | None:
    """``points`` and a copy pushed :data:`SLAB_THICKNESS` of their diagonal behind their
    plane (against ``facing``, the side they were seen from), when they form a flat
    sheet (:data:`FLAT_SHEET`); None otherwise.

    Parameters
    ----------
    points : (P, 3) float
    facing : (3,) float
        Any vector on the seen side of the sheet (e.g. the open mesh's mean normal).

    Returns
    -------
    (2P, 3) float or None
        None also for fewer than 3 points or a single position.
    """
    points = np.asarray(points, dtype=np.float64)
    normal, flatness = sheet_plane(points)
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
    if len(points) < 3 or diagonal == 0.0 or flatness > FLAT_SHEET:
        return None
    if float(normal @ np.asarray(facing, dtype=np.float64)) < 0:
        normal = -normal
    return np.concatenate([points, points - SLAB_THICKNESS * diagonal * normal])
