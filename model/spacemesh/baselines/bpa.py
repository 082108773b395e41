"""Ball pivoting (BPA): MeshLab's ``generate_surface_reconstruction_ball_pivoting``.

The ball radius is MeshLab's automatic guess from the point spacing (``ballradius``
0%), as a user would leave it. The normals only orient the triangles. BPA interpolates
the input points, so its output keeps every input point as a vertex and usually has
holes where the sampling is sparse.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray


def ball_pivoting(points: FloatArray, normals: FloatArray, *, radius: float = 0.0) -> PolygonMesh:
    """Ball-pivoting reconstruction of an oriented point cloud.

    Parameters
    ----------
    points, normals : (P, 3) float
    radius : float
        Ball radius in the points' units (0: MeshLab's automatic guess).

    Returns
    -------
    PolygonMesh
        A triangle mesh in the points' frame (unreferenced vertices removed).
    """
    import pymeshlab

    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(
        pymeshlab.Mesh(
            vertex_matrix=np.asarray(points, np.float64),
            v_normals_matrix=np.asarray(normals, np.float64),
        )
    )
    ball = pymeshlab.PureValue(radius) if radius > 0 else pymeshlab.PercentageValue(0.0)
    meshset.generate_surface_reconstruction_ball_pivoting(ballradius=ball)
    meshset.meshing_remove_unreferenced_vertices()
    current = meshset.current_mesh()
    return PolygonMesh.from_faces(current.vertex_matrix(), current.face_matrix())
