"""Untangling: faces that cross other faces are smoothed apart, locally.

The decode can return faces that pass through others (a fold where the connectivity
network joined vertices across a thin part), and the geometry stage's guard only keeps
it from adding crossings (:mod:`spacemesh.geometry.stage`). :func:`untangle` removes
them: each round moves the vertices of crossing faces part of the way to the centroid of
their neighbours (after :data:`RING_AFTER` rounds their one-ring moves too), until no
face crosses another (:func:`spacemesh.geometry.intersections.self_intersecting_faces`,
the exact test). When smoothing leaves faces crossing (two sheets that passed through
each other), their vertices are pushed along their normals instead, outward and then
inward (:func:`_pushed`). Connectivity never changes, so the mesh stays a closed
oriented manifold; vertices away from the crossings never move. The result is kept only
when it has fewer crossing faces than the input.

On the 27 dev meshes, the 4 outputs that still crossed after the seed choice
(docs/GEOMETRY.md) came out clean in 1 to 7 rounds, at a CD cost of 3% to 40% on those
four (gear 3.91 -> 4.70e-3, scorpion 2.90 -> 4.06e-3).
"""

from __future__ import annotations

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.geometry.intersections import CrossingFaces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import uniform_adjacency, vertices_of

#: Most smoothing rounds.
MAX_ROUNDS = 30
#: Share of the way to the neighbours' centroid a vertex moves per round.
STEP = 0.5
#: Rounds after which the one-ring of the crossing faces' vertices moves too.
RING_AFTER = 5
#: Most rounds of pushing crossing faces apart along their normals, each way, when
#: smoothing leaves some crossing (:func:`_pushed`).
PUSH_ROUNDS = 40
#: How far a push moves a vertex per round, a share of the mean edge length.
PUSH_STEP = 0.1
#: Pushing one way stops after this many rounds without fewer crossing faces.
PUSH_PATIENCE = 8


def untangle(mesh: PolygonMesh, *, max_rounds: int = MAX_ROUNDS
             ) -> tuple[PolygonMesh, dict[str, int | float]]:
    """``mesh`` with crossing faces smoothed apart (see the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
    max_rounds : int

    Returns
    -------
    mesh : PolygonMesh
        The same connectivity; vertices moved only where faces crossed.
    stats : dict
        ``untangle_rounds`` (0 when nothing crossed), ``crossing_before`` and
        ``crossing_after`` (shares of faces).
    """
    tracker = CrossingFaces(mesh)  # each round tests again only what moved
    hit = tracker.faces()  # (F,) bool
    before = float(hit.mean()) if mesh.n_faces else 0.0
    if not hit.any():
        return mesh, {"untangle_rounds": 0, "crossing_before": 0.0, "crossing_after": 0.0}
    n = mesh.n_vertices
    adjacency = uniform_adjacency(n, mesh.halfedges)  # (V, V) symmetric, 1 per edge
    degree = np.maximum(np.asarray(adjacency.sum(axis=1)).ravel(), 1.0)  # (V,)
    positions = mesh.vertices.astype(np.float64).copy()  # (V, 3)
    best, best_share, rounds = mesh, before, 0
    for rounds in range(1, max_rounds + 1):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        crossing = vertices_of(mesh, hit)  # (V,)
        if rounds > RING_AFTER:
            crossing |= (adjacency @ crossing.astype(np.float64)) > 0
        centroid = (adjacency @ positions) / degree[:, None]  # (V, 3)
        positions[crossing] += STEP * (centroid[crossing] - positions[crossing])
        moved = mesh.with_vertices(positions.copy())
        hit = tracker.move(positions)
        share = float(hit.mean())
        if share < best_share:
            best, best_share = moved, share
        if not hit.any():
            break
    stats: dict[str, int | float] = {"untangle_rounds": rounds, "crossing_before": before,
                                     "crossing_after": best_share}
    # smoothing left faces crossing: push them apart, from the least crossed smoothing
    # and from the input (smoothing can gather two sheets into one tangle)
    starts = [best] if best is mesh else [best, mesh]
    for start, sign in ((start, sign) for start in starts for sign in (1.0, -1.0)):
        if best_share == 0:
            break
        pushed, share, pushes = _pushed(start, sign, max_rounds=PUSH_ROUNDS)
        if share < best_share:
            best, best_share = pushed, share
            stats.update(crossing_after=share, untangle_pushes=int(sign) * pushes)
    return best, stats


def _pushed(mesh: PolygonMesh, sign: float, *, max_rounds: int
            ) -> tuple[PolygonMesh, float, int]:
    """``mesh`` with the vertices of its crossing faces pushed along their normals
    (``sign`` 1: outward, -1: inward) by :data:`PUSH_STEP` of the mean edge length a
    round, until no face crosses (or :data:`PUSH_PATIENCE` rounds bring no fewer); the
    least crossed mesh seen, its share of crossing faces and the rounds that made it.

    Smoothing cannot part two sheets that passed through each other (a thin part whose
    sides swapped, a fold at a crease): the centroid of a vertex's neighbours lies in
    the same tangle. Along the normals, the sheets of a swapped thin part move apart
    outward, a sheet pushed through another back inward; both are tried."""
    tracker = CrossingFaces(mesh)
    hit = tracker.faces()  # (F,) bool
    best, best_share, best_round = mesh, float(hit.mean()), 0
    edges = mesh.vertices[mesh.halfedges]  # (S, 2, 3)
    step = PUSH_STEP * float(np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1).mean())
    positions = mesh.vertices.astype(np.float64).copy()  # (V, 3)
    current = mesh
    for rounds in range(1, max_rounds + 1):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        crossing = vertices_of(mesh, hit)  # (V,)
        positions[crossing] += sign * step * current.vertex_normals()[crossing]
        current = mesh.with_vertices(positions.copy())
        hit = tracker.move(positions)
        share = float(hit.mean())
        if share < best_share:
            best, best_share, best_round = current, share, rounds
        if not hit.any() or rounds - best_round >= PUSH_PATIENCE:
            break
    return best, best_share, best_round
