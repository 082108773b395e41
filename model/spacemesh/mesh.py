"""The polygon mesh type used everywhere: vertices plus variable-size faces in CSR form.

A face is a cyclic sequence of vertex indices, counter-clockwise seen from outside.
Faces are stored flat (``face_indices``) with offsets (``face_offsets``), so triangle,
quad and n-gon meshes share one representation without padding.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from spacemesh.typed import ArrayLike, FloatArray, IntArray


@dataclass(frozen=True, eq=False)
class PolygonMesh:
    """An oriented polygon mesh.

    Parameters
    ----------
    vertices : (V, 3) float64
        Vertex positions.
    face_indices : (S,) int64
        The vertex indices of all faces, concatenated.
    face_offsets : (F + 1,) int64
        Face ``f`` is ``face_indices[face_offsets[f]:face_offsets[f + 1]]``.
    """

    vertices: FloatArray
    face_indices: IntArray
    face_offsets: IntArray
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        indices = np.ascontiguousarray(self.face_indices, dtype=np.int64).reshape(-1)
        offsets = np.ascontiguousarray(self.face_offsets, dtype=np.int64).reshape(-1)
        if offsets.size == 0 or offsets[0] != 0 or offsets[-1] != indices.size:
            raise ValueError("face_offsets must start at 0 and end at len(face_indices)")
        if np.any(np.diff(offsets) < 0):
            raise ValueError("face_offsets must be non-decreasing")
        if indices.size and (indices.min() < 0 or indices.max() >= len(vertices)):
            raise ValueError("a face refers to a vertex that does not exist")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "face_indices", indices)
        object.__setattr__(self, "face_offsets", offsets)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_faces(
        cls, vertices: ArrayLike, faces: Iterable[Sequence[int] | IntArray] | np.ndarray
    ) -> PolygonMesh:
        """Build a mesh from positions and a list of faces (or an (F, k) array).

        Parameters
        ----------
        vertices : (V, 3) array_like
            Vertex positions.
        faces : iterable of int sequences, or (F, k) int array
            Each face as a cyclic list of vertex indices.

        Returns
        -------
        PolygonMesh
        """
        if isinstance(faces, np.ndarray) and faces.ndim == 2:
            sizes = np.full(len(faces), faces.shape[1], dtype=np.int64)
            indices = faces.reshape(-1).astype(np.int64)
        else:
            face_list = [np.asarray(f, dtype=np.int64).reshape(-1) for f in faces]
            sizes = np.array([len(f) for f in face_list], dtype=np.int64)
            indices = np.concatenate(face_list) if face_list else np.zeros(0, dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        return cls(np.asarray(vertices, dtype=np.float64).reshape(-1, 3), indices, offsets)

    @classmethod
    def empty(cls) -> PolygonMesh:
        """The mesh with no vertices and no faces."""
        return cls(np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(1, np.int64))

    # ------------------------------------------------------------------ basic views
    @property
    def n_vertices(self) -> int:
        """Number of vertices (including unreferenced ones)."""
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        """Number of faces."""
        return len(self.face_offsets) - 1

    @property
    def face_sizes(self) -> IntArray:
        """(F,) number of sides of each face."""
        return np.diff(self.face_offsets)

    @property
    def faces(self) -> list[IntArray]:
        """The faces as a list of index arrays."""
        return np.split(self.face_indices, self.face_offsets[1:-1]) if self.n_faces else []

    @property
    def face_of_corner(self) -> IntArray:
        """(S,) the face each entry of ``face_indices`` belongs to."""
        return np.repeat(np.arange(self.n_faces, dtype=np.int64), self.face_sizes)

    @property
    def next_corner(self) -> IntArray:
        """(S,) index into ``face_indices`` of the next corner in the same face."""
        position = np.arange(self.face_indices.size, dtype=np.int64)
        start = np.repeat(self.face_offsets[:-1], self.face_sizes)
        size = np.repeat(self.face_sizes, self.face_sizes)
        return start + (position - start + 1) % np.maximum(size, 1)

    @property
    def halfedges(self) -> IntArray:
        """(S, 2) directed face sides ``(origin, target)`` in face order."""
        return np.stack([self.face_indices, self.face_indices[self.next_corner]], axis=1)

    @property
    def edges(self) -> IntArray:
        """(E, 2) unique undirected edges with ``edges[:, 0] < edges[:, 1]``, sorted."""
        cached = self._cache.get("edges")
        if cached is None:
            he = np.sort(self.halfedges, axis=1)
            cached = np.unique(he, axis=0) if len(he) else np.zeros((0, 2), np.int64)
            self._cache["edges"] = cached
        return cached

    def degree_histogram(self) -> dict[int, int]:
        """Face-degree counts, e.g. ``{3: 120, 4: 8}``."""
        sizes, counts = np.unique(self.face_sizes, return_counts=True)
        return {int(s): int(c) for s, c in zip(sizes, counts, strict=True)}

    def is_triangle_mesh(self) -> bool:
        """True when every face has three sides."""
        return bool(np.all(self.face_sizes == 3))

    # ------------------------------------------------------------------ derived meshes
    def with_vertices(self, vertices: ArrayLike) -> PolygonMesh:
        """The same connectivity with new positions (for example after denormalising)."""
        return PolygonMesh(
            np.asarray(vertices, dtype=np.float64), self.face_indices, self.face_offsets
        )

    def remove_unreferenced_vertices(self) -> tuple[PolygonMesh, IntArray]:
        """Drop vertices used by no face.

        Returns
        -------
        mesh : PolygonMesh
            The compacted mesh.
        kept : (V',) int64
            Original index of each kept vertex.
        """
        kept = np.unique(self.face_indices)
        remap = np.full(self.n_vertices, -1, dtype=np.int64)
        remap[kept] = np.arange(len(kept))
        mesh = PolygonMesh(self.vertices[kept], remap[self.face_indices], self.face_offsets)
        return mesh, kept

    def reindexed(self, order: IntArray) -> PolygonMesh:
        """Renumber vertices so that new vertex ``n`` is old vertex ``order[n]``."""
        inverse = np.empty_like(order)
        inverse[order] = np.arange(len(order))
        return PolygonMesh(self.vertices[order], inverse[self.face_indices], self.face_offsets)

    def face_key_set(self) -> set[tuple[int, ...]]:
        """Faces as a set of tuples, each rotated to start at its smallest index.

        Two meshes have the same connectivity exactly when these sets are equal
        (orientation matters: a reversed face is a different key).
        """
        if self.n_faces == 0:
            return set()
        sizes = self.face_sizes
        start = self.face_offsets[:-1]
        # position of each face's smallest index, then a rotated gather
        smallest = np.minimum.reduceat(self.face_indices, start) if len(start) else start
        is_min = self.face_indices == np.repeat(smallest, sizes)
        corner = np.arange(self.face_indices.size)
        first_min = np.full(self.n_faces, np.iinfo(np.int64).max)
        np.minimum.at(first_min, self.face_of_corner, np.where(is_min, corner, first_min.max()))
        local = corner - np.repeat(start, sizes)
        shift = np.repeat(first_min - start, sizes)
        rotated = self.face_indices[
            np.repeat(start, sizes) + (local + shift) % np.repeat(sizes, sizes)
        ]
        rows = np.split(rotated, self.face_offsets[1:-1])
        return {tuple(r.tolist()) for r in rows}

    def face_centroids(self) -> FloatArray:
        """(F, 3) the mean of each face's corners."""
        if self.n_faces == 0:
            return np.zeros((0, 3))
        corners = self.vertices[self.face_indices]  # (S, 3)
        return np.add.reduceat(corners, self.face_offsets[:-1], axis=0) / self.face_sizes[:, None]

    def face_normals(self) -> FloatArray:
        """(F, 3) unit normals by Newell's method (robust for non-planar polygons)."""
        normal = self._area_vectors()
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        return normal / np.where(length > 0, length, 1.0)

    def vertex_normals(self) -> FloatArray:
        """(V, 3) unit normals of the vertices: the sum of their faces' area-weighted
        normals (Newell's), zero at a vertex without faces or whose faces cancel."""
        total = np.zeros((self.n_vertices, 3))
        np.add.at(total, self.face_indices, self._area_vectors()[self.face_of_corner])
        length = np.linalg.norm(total, axis=1, keepdims=True)
        return total / np.where(length > 0, length, 1.0)

    def _area_vectors(self) -> FloatArray:
        """(F, 3) each face's normal times twice its area (Newell's method)."""
        v = self.vertices[self.face_indices]
        w = self.vertices[self.face_indices[self.next_corner]]
        cross = np.stack(
            [
                (v[:, 1] - w[:, 1]) * (v[:, 2] + w[:, 2]),
                (v[:, 2] - w[:, 2]) * (v[:, 0] + w[:, 0]),
                (v[:, 0] - w[:, 0]) * (v[:, 1] + w[:, 1]),
            ],
            axis=1,
        )
        normal = np.zeros((self.n_faces, 3))
        np.add.at(normal, self.face_of_corner, cross)
        return normal

    def __repr__(self) -> str:
        return (
            f"PolygonMesh(n_vertices={self.n_vertices}, n_faces={self.n_faces}, "
            f"degrees={self.degree_histogram()})"
        )
