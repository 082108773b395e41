"""Classic mesh repair, for comparison with SpaceMesh's repair (inpainting).

- :func:`meshfix`: MeshFix (Attene 2010) through ``pymeshfix``: removes
  self-intersections, degenerate and non-manifold elements, keeps the largest
  component and closes every hole. It rebuilds the triangulation near defects.
- :func:`fill_holes_trimesh`: ``trimesh.repair.fill_holes``: closes boundary loops of
  three or four edges with new faces and leaves everything else alone (larger holes
  stay open: trimesh only fans them when asked, which is wrong for non-convex holes).

Both take and return :class:`~spacemesh.mesh.PolygonMesh` (polygons are triangulated
first; the results are triangle meshes). ``pymeshfix`` is imported only when used.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangles_of


def meshfix(mesh: PolygonMesh, *, keep_largest: bool = True) -> PolygonMesh:
    """Repair a mesh with MeshFix.

    Parameters
    ----------
    mesh : PolygonMesh
    keep_largest : bool
        Remove every component but the largest before repairing (MeshFix's default).

    Returns
    -------
    PolygonMesh
        A triangle mesh.
    """
    import pymeshfix

    tri, _ = triangles_of(mesh)
    vertices, faces = pymeshfix.clean_from_arrays(
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(tri, dtype=np.int32),
        remove_smallest_components=keep_largest,
    )
    return PolygonMesh.from_faces(vertices, np.asarray(faces, np.int64).reshape(-1, 3))


def fill_holes_trimesh(mesh: PolygonMesh) -> PolygonMesh:
    """Close the boundary loops of a mesh with ``trimesh.repair.fill_holes``.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    PolygonMesh
        A triangle mesh; vertices are kept as they are (none merged or removed).
    """
    import trimesh

    tri, _ = triangles_of(mesh)
    result = trimesh.Trimesh(mesh.vertices, tri, process=False)
    trimesh.repair.fill_holes(result)
    return PolygonMesh.from_faces(np.asarray(result.vertices), np.asarray(result.faces))
