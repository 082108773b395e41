"""Long faces split along their strongest missing diagonal.

A network trained on triangle meshes should output triangles. Where it misses an edge,
the decode still makes a valid mesh, but the two triangles on either side of the missed
edge come out as one quad (or, around several misses, a larger polygon). For such a
model the decode can finish its faces: a face with more than ``max_sides`` sides is cut
along the diagonal whose embedding distance is smallest (the pair the network comes
closest to joining) among those that are not an edge already, and the two parts are cut
again until every face is short enough or has no diagonal left to cut.

Cutting a face whose vertices are distinct along a new edge keeps the mesh a closed
oriented manifold: the new edge has one halfedge in each part, the two parts keep the
face's orientation, and the fans at the two ends gain one face each without splitting.
So :func:`split_long_faces` keeps the decode's guarantee.
"""

from __future__ import annotations

import numpy as np

from spacemesh.connectivity import Connectivity
from spacemesh.encode import connectivity_from_faces
from spacemesh.primitives import edge_keys
from spacemesh.spacetime import operand_distances
from spacemesh.typed import FloatArray, IntArray


def _cut(face: IntArray, operands: tuple[FloatArray, FloatArray], edges: set[int], n: int,
         max_sides: int) -> list[IntArray]:
    """Cut one face (distinct vertices, in order) until its parts are short enough."""
    parts, done = [face], []
    while parts:
        part = parts.pop()
        m = len(part)
        if m <= max_sides:
            done.append(part)
            continue
        i, j = np.triu_indices(m, 2)
        diagonal = ~((i == 0) & (j == m - 1))  # the first and last corners are a side
        i, j = i[diagonal], j[diagonal]
        keys = edge_keys(np.stack([part[i], part[j]], axis=1), n)
        free = np.fromiter((k not in edges for k in keys.tolist()), bool, len(keys))
        if not free.any():
            done.append(part)
            continue
        distance = operand_distances(operands, part[i], part[j])  # (D,)
        best = int(np.flatnonzero(free)[np.argmin(distance[free])])
        edges.add(int(keys[best]))
        s, t = int(i[best]), int(j[best])
        parts.append(part[s : t + 1])
        parts.append(np.concatenate([part[t:], part[: s + 1]]))
    return done


def split_long_faces(
    connectivity: Connectivity, operands: tuple[FloatArray, FloatArray], max_sides: int
) -> tuple[Connectivity, int]:
    """Cut every face of more than ``max_sides`` sides along its strongest diagonals.

    Parameters
    ----------
    connectivity : Connectivity
        A valid decode (every face visits distinct vertices).
    operands : tuple of two (N, k') float arrays
        Distance operands ``a, b`` with ``d(i, j) = a_i . b_j``
        (:func:`spacemesh.spacetime.distance_operands`).
    max_sides : int
        At least 3.

    Returns
    -------
    connectivity : Connectivity
        The same vertices, with the new edges.
    added : int
        Diagonals added.
    """
    if max_sides < 3:
        raise ValueError(f"max_sides must be at least 3 (got {max_sides})")
    indices, offsets = connectivity.faces()
    sides = np.diff(offsets)
    if not (sides > max_sides).any():
        return connectivity, 0
    n = connectivity.n_vertices
    edges = set(edge_keys(connectivity.edges, n).tolist())
    before = len(edges)
    faces: list[IntArray] = []
    for f in range(len(sides)):
        face = indices[offsets[f] : offsets[f + 1]]
        faces.extend(_cut(face, operands, edges, n, max_sides) if len(face) > max_sides else [face])
    return connectivity_from_faces(faces, n), len(edges) - before
