"""Per-shape descriptors stored with each shape: sharp edges, concavity, genus."""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh

#: Dihedral turn (angle between face normals) above which an edge is sharp.
SHARP_DEGREES = 30.0


def sharp_edges(mesh: PolygonMesh, degrees: float = SHARP_DEGREES) -> tuple[int, int]:
    """Count convex and concave sharp edges of a closed, oriented polygon mesh.

    An edge is sharp when its two face normals differ by more than ``degrees``.
    It is concave when the second face's centroid lies above the first face's
    plane (the surface turns inward, as at the floor of a pocket).

    Parameters
    ----------
    mesh : PolygonMesh
    degrees : float

    Returns
    -------
    n_convex : int
    n_concave : int
    """
    he = mesh.halfedges  # (S, 2)
    face = mesh.face_of_corner
    key = np.minimum(he[:, 0], he[:, 1]) * mesh.n_vertices + np.maximum(he[:, 0], he[:, 1])
    order = np.argsort(key, kind="stable")
    sk = key[order]
    pair = np.flatnonzero(sk[1:] == sk[:-1])
    f1, f2 = face[order[pair]], face[order[pair + 1]]
    normals = mesh.face_normals()
    centroids = np.zeros((mesh.n_faces, 3))
    np.add.at(centroids, face, mesh.vertices[mesh.face_indices])
    centroids /= mesh.face_sizes[:, None]
    sharp = np.einsum("ij,ij->i", normals[f1], normals[f2]) < np.cos(np.radians(degrees))
    origin = mesh.vertices[he[order[pair], 0]]
    above = np.einsum("ij,ij->i", normals[f1], centroids[f2] - origin) > 0
    return int(np.sum(sharp & ~above)), int(np.sum(sharp & above))


def shape_features(mesh: PolygonMesh) -> dict:
    """JSON-ready descriptors of a stored shape.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    dict
        ``concave_sharp`` and ``convex_sharp`` (bool), ``n_concave_sharp_edges`` and
        ``n_convex_sharp_edges`` (int).
    """
    convex, concave = sharp_edges(mesh)
    return {
        "concave_sharp": concave > 0,
        "convex_sharp": convex > 0,
        "n_concave_sharp_edges": concave,
        "n_convex_sharp_edges": convex,
    }
