"""Face and vertex masks of a polygon mesh: faces touching vertices, vertices of faces,
the mesh restricted to some faces, some faces flipped."""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import BoolArray


def faces_touching(mesh: PolygonMesh, vertices: BoolArray) -> BoolArray:
    """(F,) faces with at least one corner in ``vertices``.

    Parameters
    ----------
    mesh : PolygonMesh
    vertices : (V,) bool

    Returns
    -------
    (F,) bool
    """
    return np.bincount(mesh.face_of_corner, vertices[mesh.face_indices],
                       minlength=mesh.n_faces) > 0


def vertices_of(mesh: PolygonMesh, faces: BoolArray) -> BoolArray:
    """(V,) vertices that are a corner of some face in ``faces``.

    Parameters
    ----------
    mesh : PolygonMesh
    faces : (F,) bool

    Returns
    -------
    (V,) bool
    """
    marked = np.zeros(mesh.n_vertices, dtype=bool)
    marked[mesh.face_indices[faces[mesh.face_of_corner]]] = True
    return marked


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
