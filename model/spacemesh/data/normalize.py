"""Normalisation and canonical ordering of stored meshes.

Vertices are centred on their bounding box and scaled so that the longest axis
spans [-1, 1], then sorted z-y-x as in PolyGen (z is the primary key). Faces are
rotated to start at their smallest vertex index and sorted, so that a shape's
stored bytes depend only on its geometry and connectivity.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives.frame import normalize


def sort_zyx(mesh: PolygonMesh) -> PolygonMesh:
    """Sort vertices by z, then y, then x, and faces canonically.

    Each face is rotated to start at its smallest (new) vertex index, and faces are
    sorted lexicographically by their index sequences (shorter first on ties), as
    PolyGen orders its faces.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    PolygonMesh
    """
    v = mesh.vertices
    order = np.lexsort((v[:, 0], v[:, 1], v[:, 2]))  # last key (z) is the primary one
    mesh = mesh.reindexed(order.astype(np.int64))
    if mesh.n_faces == 0:
        return mesh
    sizes = mesh.face_sizes  # (F,)
    starts = mesh.face_offsets[:-1]
    indices = mesh.face_indices
    # Rotate each face to start at its smallest vertex index.
    smallest = np.minimum.reduceat(indices, starts)  # (F,)
    position = np.arange(indices.size) - np.repeat(starts, sizes)  # corner within its face
    is_min = indices == np.repeat(smallest, sizes)
    first = np.full(len(sizes), np.iinfo(np.int64).max)
    np.minimum.at(first, mesh.face_of_corner[is_min], position[is_min])
    rotated = np.repeat(starts, sizes) + (position + np.repeat(first, sizes)) % np.repeat(
        sizes, sizes
    )
    indices = indices[rotated]
    # Sort faces lexicographically; padding with -1 puts a prefix before its extensions.
    padded = np.full((len(sizes), int(sizes.max())), -1, dtype=np.int64)
    padded[mesh.face_of_corner, position] = indices
    face_order = np.lexsort(padded.T[::-1])
    padded = padded[face_order]
    return PolygonMesh(
        mesh.vertices, padded[padded >= 0], np.concatenate([[0], np.cumsum(sizes[face_order])])
    )


def canonical(mesh: PolygonMesh, dtype: type = np.float32) -> PolygonMesh:
    """Normalise, round positions to the storage dtype, and sort z-y-x.

    Parameters
    ----------
    mesh : PolygonMesh
    dtype : numpy dtype
        Storage precision of positions; rounding happens before sorting so that the
        order is that of the stored values.

    Returns
    -------
    PolygonMesh
        What is stored (and validated).
    """
    normal, _, _ = normalize(mesh)
    rounded = normal.with_vertices(normal.vertices.astype(dtype).astype(np.float64))
    return sort_zyx(rounded)
