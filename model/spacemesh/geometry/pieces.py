"""Pieces: the points' own piece count, and fragments of a decoded mesh.

:func:`point_pieces` estimates how many pieces the surface that the points sample has:
the connected groups of points, two points joined when they lie within
:data:`POINT_PIECE_SPACINGS` median spacings of each other, counting only groups of at
least :data:`MIN_PIECE_SHARE` of the points (fewer are outliers). The pipeline prefers a
seed whose mesh has that many pieces, and tries the model's ``sampler.retry_seeds``
more seeds when none of the request's has (:class:`spacemesh.runtime.MeshGenerator`). On the 27 dev
meshes every cloud (2,048 points) is one group at 4 spacings (several hundred at 2),
and the estimate equals the object's pieces on 26 (the 27th is three parts that touch).

Fragments: tiny pieces of a decoded mesh that sit beside a larger one.

The connectivity network sometimes closes three to eight vertices near a larger piece
into a piece of their own: a flat two-triangle pillow or a small tetrahedral knot on the
surface of the part they belong to. Such a fragment adds a piece that the points do not
have (the output's topology disagrees with the object's) and covers almost nothing, so
:func:`drop_fragments` removes it. A small piece *away* from the others (a separate part
of the object) is kept, however small, unless it is a two-face pillow, which encloses
nothing wherever it lies; every piece of a mesh that has nothing but fragments is kept.

Removing whole closed pieces keeps a closed oriented manifold closed, oriented and
manifold: the decode's guarantee holds for the result.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels, faces_subset, triangle_areas, triangles_of
from spacemesh.topology import edge_connected_faces, weld_equal_positions
from spacemesh.typed import FloatArray, IntArray

#: Points within this many median nearest-neighbour spacings are one piece.
POINT_PIECE_SPACINGS = 4.0
#: A group of points is a piece when it holds at least this share of the points.
MIN_PIECE_SHARE = 0.01


def point_pieces(points: FloatArray) -> int:
    """How many pieces the surface sampled by ``points`` has (the module docstring).

    Parameters
    ----------
    points : (P, 3) float
        Finite points (a few thousand: the encoder's subset).

    Returns
    -------
    int
        At least 1 for two or more points; 0 for fewer.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) < 2:
        return 0
    tree = cKDTree(points)
    gaps, _ = tree.query(points, k=2)  # (P, 2): self, nearest other
    spacing = float(np.median(gaps[:, 1]))
    if spacing <= 0:
        spacing = float(np.mean(gaps[:, 1])) or 1.0
    pairs = tree.query_pairs(POINT_PIECE_SPACINGS * spacing, output_type="ndarray")  # (E, 2)
    _, label = component_labels(len(points), pairs)  # (P,)
    sizes = np.bincount(label)
    return max(1, int(np.sum(sizes >= MIN_PIECE_SHARE * len(points))))


@dataclass(frozen=True)
class FragmentPolicy:
    """What counts as a fragment.

    Attributes
    ----------
    max_vertices : int
        A fragment has at most this many vertices...
    max_area_share : float
        ... at most this share of the mesh's area...
    max_gap_edges : float
        ... and a vertex within this many median edge lengths of a vertex of a larger
        piece (a piece further away is a part of its own).
    """

    max_vertices: int = 8
    max_area_share: float = 0.02
    max_gap_edges: float = 2.0


def drop_fragments(mesh: PolygonMesh, policy: FragmentPolicy | None = None
                   ) -> tuple[PolygonMesh, int]:
    """``mesh`` without its fragments (see the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
        A valid decode (closed oriented manifold pieces).
    policy : FragmentPolicy, optional

    Returns
    -------
    mesh : PolygonMesh
        The same mesh when it has no fragment; otherwise its other pieces, with unused
        vertices removed.
    dropped : int
        How many pieces were removed.
    """
    policy = policy or FragmentPolicy()
    if mesh.n_faces == 0:
        return mesh, 0
    n_pieces, label = edge_connected_faces(weld_equal_positions(mesh))  # (F,) piece of each face
    if n_pieces < 2:
        return mesh, 0
    fragment = _fragments(mesh, n_pieces, label, policy)  # (n_pieces,) bool
    if not fragment.any() or fragment.all():
        return mesh, 0
    kept, _ = faces_subset(mesh, ~fragment[label]).remove_unreferenced_vertices()
    return kept, int(fragment.sum())


def _fragments(mesh: PolygonMesh, n_pieces: int, label: IntArray,
               policy: FragmentPolicy) -> np.ndarray:
    """(n_pieces,) bool: which pieces are fragments. A piece of two faces is one
    wherever it lies: two faces on one loop of corners, one each way (a pillow), enclose
    nothing and coincide (:func:`spacemesh.geometry.intersections.pairs_cross` reads
    them as crossing)."""
    pillow = np.bincount(label, minlength=n_pieces) == 2  # (n_pieces,)
    tri, source = triangles_of(mesh)  # (T, 3), (T,)
    areas = triangle_areas(mesh.vertices, tri)  # (T,)
    piece_area = np.bincount(label[source], weights=areas, minlength=n_pieces)
    share = piece_area / max(float(piece_area.sum()), np.finfo(float).tiny)
    vertex_piece = np.full(mesh.n_vertices, -1, dtype=np.int64)
    vertex_piece[mesh.face_indices] = np.repeat(label, mesh.face_sizes)
    used = vertex_piece >= 0
    piece_vertices = np.bincount(vertex_piece[used], minlength=n_pieces)
    small = (piece_vertices <= policy.max_vertices) & (share <= policy.max_area_share)
    if not small.any() or small.all():
        return small | pillow
    reach = policy.max_gap_edges * _median_edge(mesh)
    large_vertices = np.flatnonzero(used & ~small[np.maximum(vertex_piece, 0)])
    tree = cKDTree(mesh.vertices[large_vertices])
    fragment = np.zeros(n_pieces, dtype=bool)
    for piece in np.flatnonzero(small):
        gaps, _ = tree.query(mesh.vertices[vertex_piece == piece])
        fragment[piece] = bool(np.min(gaps) <= reach)
    return fragment | pillow


def _median_edge(mesh: PolygonMesh) -> float:
    """The median length of the mesh's face sides."""
    sides: FloatArray = mesh.vertices[mesh.halfedges[:, 1]] - mesh.vertices[mesh.halfedges[:, 0]]
    return float(np.median(np.linalg.norm(sides, axis=1)))
