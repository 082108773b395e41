"""Face and vertex masks of a polygon mesh: faces touching vertices, vertices of faces,
the mesh restricted to some faces, some faces flipped."""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import BoolArray, IntArray


def faces_touching(mesh: PolygonMesh, vertices: BoolArray) -> BoolArray:
    """(F,) faces with at least one corner in ``vertices``.

    Only the corners in ``vertices`` are located (a binary search in the face offsets),
    so the cost is one pass over the corners and no per-corner face array: the repair's
    fills call this hundreds of times on meshes of 300,000 faces.

    Parameters
    ----------
    mesh : PolygonMesh
    vertices : (V,) bool

    Returns
    -------
    (F,) bool
    """
    touching = np.zeros(mesh.n_faces, dtype=bool)
    corners = np.flatnonzero(np.asarray(vertices, dtype=bool)[mesh.face_indices])
    if len(corners):
        touching[np.searchsorted(mesh.face_offsets, corners, side="right") - 1] = True
    return touching


def vertices_of(mesh: PolygonMesh, faces: BoolArray) -> BoolArray:
    """(V,) vertices that are a corner of some face in ``faces``.

    Only the corners of the chosen faces are read (ranges of the face offsets).

    Parameters
    ----------
    mesh : PolygonMesh
    faces : (F,) bool

    Returns
    -------
    (V,) bool
    """
    marked = np.zeros(mesh.n_vertices, dtype=bool)
    marked[mesh.face_indices[corners_of(mesh, np.flatnonzero(faces))]] = True
    return marked


def corners_of(mesh: PolygonMesh, faces: IntArray) -> IntArray:
    """Indices into ``face_indices`` of the corners of the faces ``faces``, in order.

    Parameters
    ----------
    mesh : PolygonMesh
    faces : (K,) int
        Face indices.

    Returns
    -------
    (C,) int64
    """
    starts = mesh.face_offsets[faces]
    sizes = mesh.face_offsets[np.asarray(faces) + 1] - starts
    total = int(sizes.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    first = np.cumsum(sizes) - sizes  # position of each face's first corner in the output
    return np.repeat(starts - first, sizes) + np.arange(total, dtype=np.int64)


def faces_subset(mesh: PolygonMesh, faces: BoolArray) -> PolygonMesh:
    """The faces ``faces`` of ``mesh``, in order, over all its vertices.

    Parameters
    ----------
    mesh : PolygonMesh
    faces : (F,) bool

    Returns
    -------
    PolygonMesh
        Same vertices (none removed or renumbered), only the chosen faces.
    """
    sizes = mesh.face_sizes[faces]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    return PolygonMesh(mesh.vertices, mesh.face_indices[faces[mesh.face_of_corner]], offsets)


def flip_faces(mesh: PolygonMesh, faces: BoolArray | None = None) -> PolygonMesh:
    """``mesh`` with the orientation of ``faces`` (all by default) reversed.

    Parameters
    ----------
    mesh : PolygonMesh
    faces : (F,) bool, optional

    Returns
    -------
    PolygonMesh
        Same vertices and face order; each chosen face's corners in reverse order.
    """
    start = np.repeat(mesh.face_offsets[:-1], mesh.face_sizes)  # (S,)
    end = np.repeat(mesh.face_offsets[1:], mesh.face_sizes)
    position = np.arange(mesh.face_indices.size)
    reversed_indices = mesh.face_indices[start + end - 1 - position]
    if faces is not None:
        reversed_indices = np.where(faces[mesh.face_of_corner], reversed_indices,
                                    mesh.face_indices)
    return PolygonMesh(mesh.vertices, reversed_indices, mesh.face_offsets)
