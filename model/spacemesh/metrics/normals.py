"""IN: the fraction of inaccurate normals (Supplement C).

For each point sampled on the prediction, take the ground-truth sample nearest to it;
the point's normal is *inaccurate* when the angle between the two normals exceeds 10
degrees::

    IN = |{p in P : angle(n_p, n_{g(p)}) > 10 deg}| / |P|,   g(p) = argmin_g ||p - g||

The angle is between *oriented* normals (signed dot product), so a mesh whose faces
point inward scores about 100%. NDC's normal-consistency numbers use the absolute dot
product instead; orientation is part of what a valid mesh must get right, and the
paper's wording ("the angles between its normals") does not ask to ignore it. The
direction is prediction to ground truth only, as the supplement describes.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.metrics.distance import nearest
from spacemesh.metrics.sampling import SurfaceSamples

#: Angle above which a normal is inaccurate, in degrees.
IN_DEGREES = 10.0


def normal_angles(
    pred: SurfaceSamples, gt: SurfaceSamples, *, gt_tree: cKDTree | None = None
) -> np.ndarray:
    """Angle between each predicted sample's normal and its nearest ground-truth normal.

    Parameters
    ----------
    pred, gt : SurfaceSamples
        Non-empty.
    gt_tree : cKDTree, optional
        A tree of ``gt.points`` built earlier.

    Returns
    -------
    (N,) float64
        Degrees in [0, 180].
    """
    _, index = nearest(pred.points, gt_tree if gt_tree is not None else gt.points)
    dots = np.einsum("nd,nd->n", pred.normals, gt.normals[index])  # (N,)
    return np.degrees(np.arccos(np.clip(dots, -1.0, 1.0)))


def inaccurate_normals(
    pred: SurfaceSamples,
    gt: SurfaceSamples,
    degrees: float = IN_DEGREES,
    *,
    gt_tree: cKDTree | None = None,
) -> float:
    """IN: the fraction (in [0, 1]) of predicted samples whose normal is off by > ``degrees``.

    Parameters
    ----------
    pred, gt : SurfaceSamples
        Non-empty.
    degrees : float
    gt_tree : cKDTree, optional

    Returns
    -------
    float
    """
    return float(np.mean(normal_angles(pred, gt, gt_tree=gt_tree) > degrees))
