"""The convex hull of the points as a closed mesh: the last resort of the no-crossing
promise (:meth:`spacemesh.runtime.MeshGenerator._from_fewer`).

A closed mesh whose faces still cross after every other mend is made again from fewer
vertices, down to the fewest a request may ask for. Were every count down there to
cross too, the hull of the points is what is left: a convex polyhedron cannot cross
itself, and the steps after it (edges split up to the count asked for, then the fit,
whose guard lets no face cross that did not) keep it so. No evaluated request has come
near it: no output at 200 vertices has crossed on any set.

numpy and scipy only.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from spacemesh.geometry.sampling import farthest_point_sampling
from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray


def hull_mesh(points: FloatArray, max_vertices: int) -> PolygonMesh | None:
    """The convex hull of ``points`` with at most ``max_vertices`` vertices (the hull of
    the hull's own corners, farthest-point sampled down when there are more), as a
    closed triangle mesh whose faces wind counter-clockwise seen from outside.

    Parameters
    ----------
    points : (P, 3) float
    max_vertices : int
        At least 4.

    Returns
    -------
    PolygonMesh or None
        None where the points span no volume (all on one plane or line).
    """
    try:
        corners = np.asarray(points, dtype=np.float64)[ConvexHull(points).vertices]  # (H, 3)
        if len(corners) > max_vertices:
            corners = corners[farthest_point_sampling(corners, max_vertices)]
        hull = ConvexHull(corners)
    except (QhullError, ValueError):  # flat, or fewer than 4 points
        return None
    used = np.unique(hull.simplices)  # (V,) corners on the hull (all, but for rounding)
    remap = np.full(len(corners), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    triangles = remap[hull.simplices]  # (T, 3)
    vertices = corners[used]  # (V, 3)
    # qhull's facet equations point outward: wind each triangle to agree with its own
    normal = np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                      vertices[triangles[:, 2]] - vertices[triangles[:, 0]])  # (T, 3)
    inward = np.sum(normal * hull.equations[:, :3], axis=1) < 0
    triangles[inward] = triangles[inward][:, ::-1]
    return PolygonMesh.from_faces(vertices, triangles)


__all__ = ["hull_mesh"]
