"""Quadric-error decimation (pymeshlab's edge collapse, topology kept)."""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives.triangles import triangles_of


def decimate(mesh: PolygonMesh, max_vertices: int, *, genus: int) -> PolygonMesh:
    """QEM-decimate a mesh with more than ``max_vertices`` vertices (topology kept).

    Parameters
    ----------
    mesh : PolygonMesh
    max_vertices : int
    genus : int
        The mesh's genus (``check_topology(mesh).genus or 0``), which sets the face count
        that ``max_vertices`` vertices have (``2 V - 4 + 4 genus``).

    Returns
    -------
    PolygonMesh
        Triangulated and decimated, or ``mesh`` itself when it is small enough.
    """
    if mesh.n_vertices <= max_vertices:
        return mesh
    import pymeshlab  # the geometry extra

    tri, _ = triangles_of(mesh)
    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=tri.astype(np.int32)))
    meshset.meshing_decimation_quadric_edge_collapse(
        targetfacenum=max(4, 2 * max_vertices - 4 + 4 * genus),
        qualitythr=0.5,
        preservenormal=True,
        preservetopology=True,
        optimalplacement=True,
        planarquadric=True,
        autoclean=True,
    )
    current = meshset.current_mesh()
    return PolygonMesh.from_faces(current.vertex_matrix(), current.face_matrix())
