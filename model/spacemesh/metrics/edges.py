"""Sharp-feature points and the edge Chamfer distance (ECD) and edge F-score (EF1).

Edge points, as NDC's evaluation code finds them: a sample is an *edge point* when at
least one of its neighbours has a normal that is nearly perpendicular to its own::

    edge(i)  <=>  min_{j in N(i)} |n_i . n_j| < 0.2          (angle within ~78-102 deg)

The paper's Supplement C words this as "the mean dot product [...] is below 0.2"; the
NDC code it follows takes the *minimum* of the absolute dot products instead, and only
that reading finds the edges of a cube: at a point on a 90-degree edge half the
neighbours share its normal, so the mean is about 0.5 and never drops below 0.2.
``rule="mean"`` gives the literal reading (mean of the signed dot products) for
comparison.

Neighbourhood: NDC used a ball of radius 0.004 in a [-0.5, 0.5] frame with 100,000
samples, which holds about two neighbours. With the paper's 10,000 samples a fixed
radius would hold none on large shapes, so ``N(i)`` is the ``k = 8`` nearest other
samples here; the edge band is then a few sample spacings wide for every method alike.

ECD and EF1 are :func:`spacemesh.metrics.distance.chamfer_f1` on the edge points only
(squared distances summed over both directions; threshold 0.02 in the [-1, 1] frame,
like F1). Empty sets follow NDC: when the ground truth has no edge points the shape
scores ECD 0 and EF1 1; when only the prediction has none, its edge points are taken
to be the single point at the centre of the frame (the origin), which makes missing
every sharp feature expensive rather than free.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.metrics.distance import F1_THRESHOLD, DistanceScores, chamfer_f1
from spacemesh.metrics.sampling import SurfaceSamples
from spacemesh.typed import BoolArray

#: Dot-product threshold of the edge test (NDC: 0.2).
EDGE_DOT_THRESHOLD = 0.2
#: Neighbours of each sample in the edge test.
EDGE_NEIGHBOURS = 8
#: EF1 distance threshold in the [-1, 1] frame.
EF1_THRESHOLD = F1_THRESHOLD


def edge_mask(
    samples: SurfaceSamples,
    *,
    k: int = EDGE_NEIGHBOURS,
    threshold: float = EDGE_DOT_THRESHOLD,
    rule: Literal["min", "mean"] = "min",
) -> BoolArray:
    """Which samples lie on sharp features (see the module doc).

    Parameters
    ----------
    samples : SurfaceSamples
        N points with unit normals.
    k : int
        Neighbours of each sample (itself excluded).
    threshold : float
    rule : {"min", "mean"}
        ``"min"``: NDC's test, ``min_j |n_i . n_j| < threshold``. ``"mean"``: the paper's
        wording, ``mean_j n_i . n_j < threshold``.

    Returns
    -------
    (N,) bool
    """
    n = len(samples)
    if n < 2:
        return np.zeros(n, dtype=bool)
    k = min(k, n - 1)
    _, index = cKDTree(samples.points).query(samples.points, k=k + 1)  # (N, k + 1)
    index = index[:, 1:]  # drop the point itself
    dots = np.einsum("nd,nkd->nk", samples.normals, samples.normals[index])  # (N, k)
    if rule == "min":
        return np.abs(dots).min(axis=1) < threshold
    if rule == "mean":
        return dots.mean(axis=1) < threshold
    raise ValueError(f"rule must be 'min' or 'mean', not {rule!r}")


def edge_points(samples: SurfaceSamples, **options) -> SurfaceSamples:
    """The samples that :func:`edge_mask` marks (``options`` are passed on)."""
    return samples.subset(edge_mask(samples, **options))


def edge_chamfer_f1(
    pred_edges: SurfaceSamples, gt_edges: SurfaceSamples, threshold: float = EF1_THRESHOLD
) -> DistanceScores:
    """ECD and EF1 between two sets of edge points, with NDC's rules for empty sets.

    Parameters
    ----------
    pred_edges, gt_edges : SurfaceSamples
        Edge points of the prediction and of the ground truth (see :func:`edge_points`).
    threshold : float
        EF1 distance threshold.

    Returns
    -------
    DistanceScores
        ``chamfer`` is the ECD and ``f1`` the EF1.
    """
    if len(gt_edges) == 0:
        return DistanceScores(0.0, 1.0, 1.0, 1.0, 0.0, 0.0)
    pred = pred_edges.points if len(pred_edges) else np.zeros((1, 3))
    return chamfer_f1(pred, gt_edges.points, threshold)
