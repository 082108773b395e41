"""Normals estimated and oriented from the points alone, as a user of PSR would.

The baselines never see the ground-truth normals. :func:`estimate_normals` runs
MeshLab's ``compute_normal_for_point_clouds``: a plane fit to the ``k`` nearest
neighbours of each point, then orientation propagated consistently along the
neighbourhood graph (VCG's ``PointCloudNormal``), with ``smoothiter`` rounds of
neighbour averaging. Propagation fixes the *relative* sign; the global sign is then
chosen so that most normals point away from the centroid, which is right for the
closed shapes evaluated here (a user would flip an inward result the same way).

Orientation is the weak step on 2048 points of CAD-like shapes: across thin walls and
sharp edges the propagation can flip whole regions, and PSR then fails. The defaults
(``k = 16``, no smoothing) were picked to favour the baselines: on 60 held-out
synthetic shapes they oriented 92% of the normals correctly on average (10 shapes
below 90%), against 88% (19 below 90%) for MeshLab's ``k = 10`` with two smoothing
rounds; a Hoppe-style minimum-spanning-tree propagation (what Open3D's
``orient_normals_consistent_tangent_plane`` does) scored 87-89%.
"""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray

#: Neighbours of the plane fit and of the orientation graph.
NORMAL_NEIGHBOURS = 16
#: Rounds of normal smoothing.
SMOOTH_ITERATIONS = 0


def orient_outward(points: FloatArray, normals: FloatArray) -> FloatArray:
    """Flip all normals when most of them point towards the centroid.

    Parameters
    ----------
    points, normals : (P, 3) float

    Returns
    -------
    (P, 3) float64
    """
    normals = np.asarray(normals, dtype=np.float64)
    outward = np.einsum("pd,pd->p", normals, points - points.mean(axis=0))  # (P,)
    return -normals if np.mean(outward > 0) < 0.5 else normals


def estimate_normals(
    points: FloatArray, *, k: int = NORMAL_NEIGHBOURS, smooth_iterations: int = SMOOTH_ITERATIONS
) -> FloatArray:
    """Unit normals of a point cloud, consistently oriented and pointing outward.

    Parameters
    ----------
    points : (P, 3) float
    k : int
        Neighbours of the plane fit and of the orientation graph.
    smooth_iterations : int

    Returns
    -------
    (P, 3) float64
    """
    import pymeshlab

    points = np.asarray(points, dtype=np.float64)
    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=points))
    meshset.compute_normal_for_point_clouds(k=k, smoothiter=smooth_iterations)
    normals = meshset.current_mesh().vertex_normal_matrix()  # (P, 3)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return orient_outward(points, normals / np.where(length > 0, length, 1.0))
