"""Encoding: the ground-truth SpaceMesh connectivity of a closed oriented manifold mesh."""

from __future__ import annotations

import numpy as np

from spacemesh.connectivity import Connectivity, csr_from_edges, slot_lookup
from spacemesh.errors import NotManifoldError
from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology
from spacemesh.typed import IntArray


def require_closed_manifold(mesh: PolygonMesh) -> None:
    """Raise :class:`NotManifoldError` naming the defects unless ``mesh`` is encodable.

    Parameters
    ----------
    mesh : PolygonMesh
    """
    report = check_topology(mesh)
    if not report.is_closed_oriented_manifold:
        raise NotManifoldError(
            "the mesh is not a closed oriented manifold: " + "; ".join(report.defects())
        )


def encode_connectivity(mesh: PolygonMesh, check: bool = True) -> Connectivity:
    """Edges and the cyclic neighbour order at every vertex of ``mesh``.

    Each face corner ``(u, v, w)`` (``u`` before and ``w`` after ``v``) gives the
    relation ``next(u -> v) = (v -> w)``.

    Parameters
    ----------
    mesh : PolygonMesh
        A closed, oriented, manifold polygon mesh (triangles, quads or n-gons).
    check : bool
        Verify the topology first (raises :class:`NotManifoldError`).

    Returns
    -------
    Connectivity
    """
    if check:
        require_closed_manifold(mesh)
    offsets, neighbours = csr_from_edges(mesh.edges, mesh.n_vertices)
    nxt = mesh.next_corner  # (S,)
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(nxt))
    v = mesh.face_indices
    u = v[prv]
    w = v[nxt]
    successor = np.empty(len(neighbours), dtype=np.int64)
    successor[slot_lookup(offsets, neighbours, v, u)] = slot_lookup(offsets, neighbours, v, w)
    return Connectivity(mesh.n_vertices, offsets, neighbours, successor)


def connectivity_from_faces(faces: list[IntArray], n_vertices: int) -> Connectivity:
    """:func:`encode_connectivity` of polygons given as vertex cycles, unchecked.

    For the decode's own rewrites of a valid mesh (cut faces, reinserted vertices,
    flipped diagonals), which keep it a closed oriented manifold by construction.

    Parameters
    ----------
    faces : list of (m_f,) int arrays
        Vertex cycles over ``n_vertices`` vertices (unused vertices get degree 0).
    n_vertices : int

    Returns
    -------
    Connectivity
    """
    offsets = np.concatenate([[0], np.cumsum([len(f) for f in faces])]).astype(np.int64)
    indices = np.concatenate(faces).astype(np.int64) if faces else np.zeros(0, np.int64)
    mesh = PolygonMesh(np.zeros((n_vertices, 3)), indices, offsets)
    return encode_connectivity(mesh, check=False)
