"""Points sampled uniformly by area on a mesh surface, with their face normals."""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives.triangles import triangles_of
from spacemesh.typed import FloatArray


def sample_surface(
    mesh: PolygonMesh, count: int, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray]:
    """Sample points uniformly by area on the surface, with their face normals.

    Parameters
    ----------
    mesh : PolygonMesh
        A mesh with polygon faces (triangulated internally).
    count : int
        Number of points.
    rng : numpy.random.Generator

    Returns
    -------
    points : (count, 3) float32
    normals : (count, 3) float32
        Unit normal of the polygon face each point lies on (Newell's normal, so a
        slightly non-planar polygon gives one normal to all its points).

    Raises
    ------
    ValueError
        The mesh has no triangle to sample on (no face of three or more vertices).
    """
    tri, source = triangles_of(mesh)
    if not len(tri):
        raise ValueError("the mesh has no face of three or more vertices to sample points on")
    v = mesh.vertices
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]  # (T, 3) each
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)  # (T,) twice the area
    cdf = np.cumsum(area)
    pick = np.searchsorted(cdf, rng.random(count) * cdf[-1], side="right")
    pick = np.minimum(pick, len(tri) - 1)  # (count,)
    r1, r2 = rng.random(count), rng.random(count)
    flip = r1 + r2 > 1.0  # fold the unit square onto the triangle
    r1, r2 = np.where(flip, 1.0 - r1, r1), np.where(flip, 1.0 - r2, r2)
    points = a[pick] + r1[:, None] * (b[pick] - a[pick]) + r2[:, None] * (c[pick] - a[pick])
    normals = mesh.face_normals()[source[pick]]
    return points.astype(np.float32), normals.astype(np.float32)
