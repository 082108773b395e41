"""Encoding: the ground-truth SpaceMesh connectivity of a closed oriented manifold mesh."""

from __future__ import annotations

import numpy as np

from spacemesh.connectivity import Connectivity, csr_from_edges, slot_lookup
from spacemesh.errors import NotManifoldError
from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology


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
