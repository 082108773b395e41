"""The loops of a hole as simple cycles: open edges that touch at a vertex (a pinched
boundary) split there into loops that visit each vertex once (:func:`split_pinched`), so
that filling every loop joins the fans of faces at each vertex into one disc
(:func:`hole_loops`).

numpy and scipy only.
"""

from __future__ import annotations

import itertools

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels
from spacemesh.repair.cut import boundary_loops
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.typed import FloatArray, IntArray


def _fan_labels(sub: FaceSubset) -> IntArray:
    """(S,) the fan (a connected set of faces around its origin) of each halfedge's
    origin, as in :meth:`FaceSubset.fan_counts`."""
    total = len(sub.halfedges)
    has = np.flatnonzero(sub.twin >= 0)
    rot = sub.next[sub.twin[has]]
    return component_labels(total, np.stack([has, rot], axis=1))[1]


#: Most fans at one vertex whose orders :func:`_fan_cycles` tries (all of them).
MAX_FANS = 6


def _fan_cycles(p: FloatArray, v: int, arriving: list[int], leaving: list[int],
                start: IntArray, end: IntArray, fan_in: IntArray, fan_out: IntArray
                ) -> list[list[tuple[int, int]]]:
    """The pairings of the loop edges arriving at the vertex ``v`` with those leaving
    it that join the fans there in one cycle (every order of the fans is one disc once
    the gaps are filled; a pairing of shorter cycles would leave ``v`` pinched), those
    whose paired edges make the smallest angles (largest summed cosines) first; empty
    when the edges do not pair up fan by fan."""
    fans = sorted(set(fan_in[arriving].tolist()))
    into = {int(fan_in[i]): i for i in arriving}
    out = {int(fan_out[j]): j for j in leaving}
    if len(fans) > MAX_FANS or len(into) != len(fans) or sorted(out) != fans:
        return []

    def cosine(i: int, j: int) -> float:
        a, b = p[start[i]] - p[v], p[end[j]] - p[v]
        return float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-300)

    scored = []
    for rest in itertools.permutations(fans[1:]):
        cycle = [fans[0], *rest]
        pairs = [(into[a], out[b]) for a, b in zip(cycle, cycle[1:] + cycle[:1], strict=True)]
        scored.append((-sum(cosine(i, j) for i, j in pairs), pairs))
    return [pairs for _, pairs in sorted(scored, key=lambda x: x[0])]


def _trace(start: IntArray, successor: IntArray) -> list[list[int]]:
    """The cycles of ``successor`` as vertex loops (``start`` of each member)."""
    seen = np.zeros(len(start), dtype=bool)
    loops = []
    for first in range(len(start)):
        if seen[first]:
            continue
        cycle, i = [], first
        while not seen[i]:
            seen[i] = True
            cycle.append(int(start[i]))
            i = int(successor[i])
        loops.append(cycle)
    return loops


def _untangle(loop: list[int], taken: set[tuple[int, int]]) -> list[list[int]] | None:
    """A loop that visits a vertex twice (``[v, a..., v, b...]``) split by a new edge
    between a vertex of each arc into two loops that visit it once each, recursively;
    the new edge is one the mesh does not have (``taken``, updated). None when no such
    edge is found."""
    seen: dict[int, int] = {}
    for k, v in enumerate(loop):
        if v in seen:
            first = seen[v]
            break
        seen[v] = k
    else:
        return [loop]
    inner, outer = list(range(first + 1, k)), list(range(k + 1, len(loop) + first))
    outer = [x % len(loop) for x in outer]
    repeated = {v for v in loop if loop.count(v) > 1}
    pairs = sorted(((abs(i - inner[len(inner) // 2]) + abs(outer.index(j) - len(outer) // 2),
                     i, j) for i in inner for j in outer), key=lambda x: x[0])
    for _, i, j in pairs:
        a, b = loop[i], loop[j]
        key = (min(a, b), max(a, b))
        if a == b or a in repeated or b in repeated or key in taken:
            continue
        taken.add(key)
        one = [loop[x % len(loop)] for x in range(i, j + (len(loop) if j < i else 0) + 1)]
        two = [loop[x % len(loop)] for x in range(j, i + (len(loop) if i < j else 0) + 1)]
        left, right = _untangle(one, taken), _untangle(two, taken)
        return None if left is None or right is None else left + right
    return None


def split_pinched(mesh: PolygonMesh, sub: FaceSubset, open_ids: IntArray
                  ) -> list[IntArray] | None:
    """Simple loops of the open halfedges ``open_ids`` of ``sub`` (mesh direction) when
    some vertex has several of them (loops touching at a vertex, a pinched boundary).

    At such a vertex each gap between two fans of faces is one corner of one loop: a
    loop arriving along the last edge of one fan leaves along the first edge of another
    fan (never its own, which would close that fan alone and leave the vertex pinched),
    so that the fans form one cycle (:func:`_fan_cycles`; with two fans there is one;
    with more, the one whose paired edges make the smallest angles). A loop that still
    visits a vertex twice (one loop through two of its gaps) is split there by a new
    edge across it (:func:`_untangle`). Filling every loop then joins the fans at each
    vertex into one disc.

    Returns
    -------
    list of (L,) int64 or None
        Vertex cycles in the direction a filling face traverses them, or None when the
        open edges do not pair up fan by fan or a loop cannot be split.
    """
    label = _fan_labels(sub)
    he = sub.halfedges[open_ids]
    # the filling runs each open halfedge u -> w backwards: w -> u
    start, end = he[:, 1], he[:, 0]
    fan_in = label[open_ids]  # the fan at ``end`` of the face beside it (leaves ``end``)
    fan_out = label[sub.next[open_ids]]  # the fan at ``start`` (next halfedge leaves it)
    successor = np.full(len(he), -1, dtype=np.int64)
    by_start: dict[int, list[int]] = {}
    for i, v in enumerate(start.tolist()):
        by_start.setdefault(v, []).append(i)
    choices = []
    for v, leaving in by_start.items():
        arriving = np.flatnonzero(end == v).tolist()
        if len(arriving) != len(leaving):
            return None
        options = _fan_cycles(mesh.vertices, v, arriving, leaving, start, end, fan_in,
                              fan_out) if len(leaving) > 1 else [[(arriving[0], leaving[0])]]
        if not options:
            return None
        choices.append(options)
    for options in choices:
        for i, j in options[0]:
            successor[i] = j
    taken = {(int(a), int(b)) for a, b in np.sort(mesh.edges, axis=1).tolist()}
    loops = []
    for cycle in _trace(start, successor):
        pieces = _untangle(cycle, taken)
        if pieces is None:
            return None
        loops += [np.asarray(piece, dtype=np.int64) for piece in pieces]
    return loops


def hole_loops(mesh: PolygonMesh, vertices: IntArray, sub: FaceSubset | None = None
               ) -> list[IntArray] | None:
    """The open loops through ``vertices`` as simple cycles in the direction a filling
    face traverses them (loops touching at a vertex split there, :func:`split_pinched`),
    or None when they cannot be made simple. ``sub``: ``FaceSubset.of(mesh, every
    face)``, when the caller has it (it reads the whole mesh)."""
    if sub is None:
        sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    open_ids = np.flatnonzero(sub.edge_count[sub.edge] == 1)
    inside = np.zeros(mesh.n_vertices, dtype=bool)
    inside[vertices] = True
    he = sub.halfedges[open_ids]
    open_ids = open_ids[inside[he[:, 0]] & inside[he[:, 1]]]
    try:
        return boundary_loops(sub.halfedges[open_ids][:, ::-1])[3]
    except ValueError:
        return split_pinched(mesh, sub, open_ids)
