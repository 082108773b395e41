"""Splicing predicted connectivity into a hole: new faces only, kept faces untouched.

The hole of a :class:`spacemesh.repair.cut.Cut` is bounded by simple loops of boundary
vertices. The connectivity network gives embeddings to the ``B`` boundary vertices and
the ``M`` new vertices; this module turns them into the faces that fill the hole.
Local ids: boundary vertex ``b`` is ``b`` (its position in ``cut.boundary``), new vertex
``m`` is ``B + m``. The rules (docs/REPAIR.md has the full list):

1. **Edges** are the pairs below the threshold (paper Eq. 2) that join two new vertices
   or a new vertex and a boundary vertex. Boundary-boundary pairs are never added (the
   kept faces own those vertices' existing edges).
2. **Boundary vertices** keep their kept fan as fixed entries of their cyclic order: the
   fan is a path from ``n_0 = loop_next`` round to ``n_m = loop_prev``, and only its
   single gap is free. Contracting the path into one element ``P`` (row ``n_m``,
   column ``n_0``) leaves a ``(k + 1) x (k + 1)`` single-cycle problem over ``P`` and the
   ``k`` new neighbours, solved exactly as in the decode: Sinkhorn, the LAP, the
   single-orbit check and the greedy fallback (:func:`spacemesh.matching.match_cycles`).
   With ``k = 0`` the gap closes directly: ``next(n_m -> i) = (i -> n_0)``.
3. **New vertices** are matched as in :func:`spacemesh.decode.decode`.
4. **Faces** are the orbits of ``next`` over the hole halfedges ``i -> loop_next[i]`` and
   both halfedges of every new edge. Kept faces are never part of an orbit here, so
   they come back identical.
5. **Invalid results are repaired by removing new edges and vertices only**: a new
   vertex with degree below 2 goes (repeatedly); a group of new vertices joined to no
   boundary vertex goes; a face that visits a vertex twice first loses its weakest new
   edge at the repeated vertex (as in :mod:`spacemesh.decode`, for
   :data:`spacemesh.decode.EDGE_ROUNDS` rounds with ``unpinch="edge"``), then one new
   vertex (the repeated one if it is new, else the face's new vertex of highest
   degree, then lowest id), and the neighbourhoods that changed are matched again.
   After :data:`GENTLE_ROUNDS` vertex rounds every new vertex of a pinched face goes
   at once.
6. **The last resort**: with no new vertex left next to it, a loop is closed by one
   polygon face through its vertices, which is always valid (the loop is simple and
   has at least three vertices).

Every rule keeps the result an oriented manifold whose hole is closed, so a closed
manifold input gives a closed manifold output.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.connectivity import csr_from_edges, slot_lookup
from spacemesh.decode import (
    EDGE_ROUNDS,
    DecodeOptions,
    Embeddings,
    pinched_face_edges,
    repeated_in_faces,
    unpinch_candidates,
)
from spacemesh.matching import match_cycles
from spacemesh.mesh import PolygonMesh
from spacemesh.permutation import (
    group_by_degree,
    log_sinkhorn,
    mask_diagonal,
    neighbourhood_log_phi_bar,
    reduction_logits,
)
from spacemesh.primitives import component_labels, edge_keys
from spacemesh.repair.cut import Cut
from spacemesh.spacetime import edges_below_threshold
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Rounds of one-new-vertex-per-face removal before every new vertex of a pinched face
#: goes at once (as in :mod:`spacemesh.decode`).
GENTLE_ROUNDS = 12


@dataclass
class Fill:
    """The faces that close a hole, in local ids (boundary ``0..B-1``, new ``B..B+M-1``).

    Attributes
    ----------
    face_indices : (S,) int64
    face_offsets : (F + 1,) int64
        The new faces (CSR), each listing the origin of each of its halfedges.
    new_alive : (M,) bool
        New vertices that are on a face.
    edges : (E, 2) int64
        The new edges (local ids).
    stats : dict
        ``n_candidates`` (M), ``n_edges``, ``n_pruned`` (degree below 2),
        ``n_detached`` (groups joined to no boundary vertex), ``n_unpinched``
        (removed for a face visiting a vertex twice), ``n_fallbacks`` (greedy
        single-orbit matchings), ``polygon_loops`` (loops closed by one polygon),
        ``rounds``.
    """

    face_indices: IntArray
    face_offsets: IntArray
    new_alive: BoolArray
    edges: IntArray
    stats: dict = field(default_factory=dict)

    @property
    def n_faces(self) -> int:
        """Number of new faces."""
        return len(self.face_offsets) - 1


def _prune(edges: IntArray, alive: BoolArray, is_new: BoolArray, n_boundary: int
           ) -> tuple[IntArray, BoolArray, int, int]:
    """Drop new vertices of degree < 2 and new groups joined to no boundary vertex."""
    n = len(alive)
    pruned = detached = 0
    while True:
        edges = edges[alive[edges[:, 0]] & alive[edges[:, 1]]]
        degree = np.bincount(edges.reshape(-1), minlength=n)
        low = is_new & alive & (degree < 2)
        if low.any():
            alive = alive & ~low
            pruned += int(low.sum())
            continue
        if n_boundary == 0 or not (is_new & alive).any():
            return edges, alive, pruned, detached
        new_new = edges[is_new[edges[:, 0]] & is_new[edges[:, 1]]]
        _, label = component_labels(n, new_new)  # (N,)
        to_boundary = edges[~(is_new[edges[:, 0]] & is_new[edges[:, 1]])]
        anchored_vertices = to_boundary.max(axis=1)  # the new end (new ids are larger)
        anchored = np.zeros(n, dtype=bool)
        anchored[label[anchored_vertices]] = True
        lonely = is_new & alive & ~anchored[label]
        if not lonely.any():
            return edges, alive, pruned, detached
        alive = alive & ~lonely
        detached += int(lonely.sum())


@dataclass
class _Orders:
    """Cyclic orders: CSR slots of the new edges plus the contracted boundary problems."""

    offsets: IntArray  # (n + 1,)
    neighbours: IntArray  # (H,)
    local: IntArray  # (H,) for new vertices: local successor of each slot (arriving row)
    b_offsets: IntArray  # (B + 1,) rows of each boundary vertex's contracted problem
    b_perm: IntArray  # (sum(k + 1),) contracted successor, 0 = P
    n_fallbacks: int


def _match(emb: Embeddings, edges: IntArray, n_boundary: int, loop_next: IntArray,
           loop_prev: IntArray, options: DecodeOptions, previous: _Orders | None = None
           ) -> _Orders:
    """Single-cycle orders at every vertex (rules 2 and 3).

    Edges are only ever removed between rounds, so a vertex whose degree is unchanged
    since ``previous`` has the same neighbours and keeps its order.
    """
    n = emb.n_vertices
    offsets, neighbours = csr_from_edges(edges, n)
    degree = np.diff(offsets)
    k = degree[:n_boundary]
    b_offsets = np.concatenate([[0], np.cumsum(k + 1)]).astype(np.int64)
    local = np.zeros(len(neighbours), dtype=np.int64)
    b_perm = np.zeros(int(b_offsets[-1]), dtype=np.int64)
    dirty = np.ones(n, dtype=bool)
    if previous is not None:
        dirty = degree != np.diff(previous.offsets)
        clean = np.flatnonzero(~dirty & (degree > 0))
        new_clean = clean[clean >= n_boundary]
        if new_clean.size:
            sizes = degree[new_clean]
            within = np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes)
            local[np.repeat(offsets[new_clean], sizes) + within] = previous.local[
                np.repeat(previous.offsets[new_clean], sizes) + within]
        b_clean = clean[clean < n_boundary]
        if b_clean.size:
            sizes = k[b_clean] + 1
            within = np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes)
            b_perm[np.repeat(b_offsets[b_clean], sizes) + within] = previous.b_perm[
                np.repeat(previous.b_offsets[b_clean], sizes) + within]
    fallbacks = 0
    is_new = np.arange(n) >= n_boundary
    for d, vertices in group_by_degree(offsets).items():
        vertices = vertices[is_new[vertices] & dirty[vertices]]
        if d < 2 or vertices.size == 0:
            continue
        log_phi_bar = neighbourhood_log_phi_bar(
            emb.root, emb.prev, emb.next, vertices, offsets, neighbours, d,
            options.reduction, options.reduction_params, options.sinkhorn_iters,
        )
        perms, n_fb = match_cycles(log_phi_bar)  # (n_d, d)
        local[offsets[vertices][:, None] + np.arange(d)[None, :]] = perms
        fallbacks += n_fb
    # boundary vertices: element 0 is the contracted kept path P
    for size in np.unique(k + 1):
        group = np.flatnonzero((k + 1 == size) & dirty[:n_boundary])
        if size == 1 or group.size == 0:
            continue  # P -> P: the gap closes directly
        slots = offsets[group][:, None] + np.arange(size - 1)[None, :]  # (g, k)
        nbrs = neighbours[slots]
        prev_ids = np.concatenate([loop_prev[group][:, None], nbrs], axis=1)  # (g, k + 1)
        next_ids = np.concatenate([loop_next[group][:, None], nbrs], axis=1)
        logits = reduction_logits(emb.root[group], emb.prev[prev_ids], emb.next[next_ids],
                                  options.reduction, options.reduction_params)
        log_phi_bar = log_sinkhorn(mask_diagonal(logits), options.sinkhorn_iters)
        perms, n_fb = match_cycles(log_phi_bar)
        b_perm[b_offsets[group][:, None] + np.arange(size)[None, :]] = perms
        fallbacks += n_fb
    return _Orders(offsets, neighbours, local, b_offsets, b_perm, fallbacks)


def _orbits(orders: _Orders, n_boundary: int, loop_next: IntArray) -> tuple[IntArray, IntArray]:
    """Faces: orbits of ``next`` over new-edge halfedges and hole halfedges (rule 4)."""
    offsets, neighbours = orders.offsets, orders.neighbours
    n_slots = len(neighbours)
    n = len(offsets) - 1
    origin = np.repeat(np.arange(n, dtype=np.int64), np.diff(offsets))
    # every halfedge: slots 0..H-1 (u -> neighbours), then H + b for b -> loop_next[b]
    he_origin = np.concatenate([origin, np.arange(n_boundary, dtype=np.int64)])
    he_target = np.concatenate([neighbours, loop_next])
    # row of each halfedge in its target's order
    row = np.zeros(len(he_origin), dtype=np.int64)
    if n_slots:
        row[:n_slots] = slot_lookup(offsets, neighbours, neighbours, origin) - offsets[neighbours]
    into_boundary = he_target < n_boundary
    row[into_boundary & (np.arange(len(row)) < n_slots)] += 1  # contracted: 0 is P
    # row 0 of a boundary target: the hole halfedge from loop_prev (already 0)
    nxt = np.empty(len(he_origin), dtype=np.int64)
    tgt = he_target
    new_t = ~into_boundary
    nxt[new_t] = offsets[tgt[new_t]] + orders.local[offsets[tgt[new_t]] + row[new_t]]
    b = tgt[into_boundary]
    col = orders.b_perm[orders.b_offsets[b] + row[into_boundary]]
    nxt[into_boundary] = np.where(col == 0, n_slots + b, offsets[b] + col - 1)
    visited = np.zeros(len(nxt), dtype=bool)
    indices: list[int] = []
    face_offsets = [0]
    nxt_list, origin_list = nxt.tolist(), he_origin.tolist()
    for start in range(len(nxt_list)):
        if visited[start]:
            continue
        h = start
        while not visited[h]:
            visited[h] = True
            indices.append(origin_list[h])
            h = nxt_list[h]
        face_offsets.append(len(indices))
    return np.asarray(indices, dtype=np.int64), np.asarray(face_offsets, dtype=np.int64)


def _pinched_new_vertices(indices: IntArray, face_offsets: IntArray, degree: IntArray,
                          is_new: BoolArray, every: bool = False) -> tuple[IntArray, bool]:
    """One new vertex per face that visits a vertex twice (rule 5).

    With ``every``, all new vertices of those faces instead (the fast rule after
    :data:`GENTLE_ROUNDS`).

    Returns
    -------
    remove : (P,) int64
        Distinct new vertices to remove.
    stuck : bool
        A pinched face had no new vertex (never expected; the caller then removes all).
    """
    n = len(degree)
    _, repeated, _, _ = repeated_in_faces(indices, face_offsets, n)
    if repeated.size == 0:
        return repeated, False
    remove = []
    stuck = False
    for f in np.unique(repeated // n):
        verts = indices[face_offsets[f]:face_offsets[f + 1]]
        rep = repeated[repeated // n == f] % n
        candidates = rep[is_new[rep]]
        if candidates.size == 0 or every:
            candidates = np.unique(verts[is_new[verts]])
        if candidates.size == 0:
            stuck = True
            continue
        if every:
            remove.extend(candidates.tolist())
            continue
        order = np.lexsort((candidates, -degree[candidates]))
        remove.append(int(candidates[order[0]]))
    return np.unique(np.asarray(remove, dtype=np.int64)), stuck


def fill_hole(
    emb: Embeddings,
    n_boundary: int,
    loop_next: IntArray,
    loop_prev: IntArray,
    options: DecodeOptions | None = None,
) -> Fill:
    """Faces that close the hole from the embeddings of its boundary and new vertices.

    Parameters
    ----------
    emb : Embeddings
        Of the ``B`` boundary vertices (first, in ``cut.boundary`` order) and then the
        ``M`` new vertices.
    n_boundary : int
        ``B``.
    loop_next, loop_prev : (B,) int64
        From :class:`spacemesh.repair.cut.Cut`.
    options : DecodeOptions, optional
        How embeddings are read (distance, reduction, Sinkhorn iterations).

    Returns
    -------
    Fill
    """
    options = options or DecodeOptions()
    n = emb.n_vertices
    is_new = np.arange(n) >= n_boundary
    # numpy types all(axis=...) as bool | array; with an axis on a 2-D array it is an array
    finite: BoolArray = np.isfinite(emb.adjacency).all(axis=1)  # type: ignore[assignment]
    clean = Embeddings(
        np.where(finite[:, None], emb.adjacency, 0.0),
        float(emb.tau) if np.isfinite(emb.tau) else -np.inf,
        *(np.nan_to_num(np.asarray(a, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
          for a in (emb.root, emb.prev, emb.next)),
    )
    alive = np.ones(n, dtype=bool) & (finite | ~is_new)
    edges = np.zeros((0, 2), dtype=np.int64)
    if is_new.any() and np.isfinite(clean.tau):
        edges = edges_below_threshold(clean.adjacency, clean.tau, options.distance,
                                      options.n_space, alive, options.max_degree)
        edges = edges[is_new[edges[:, 0]] | is_new[edges[:, 1]]]  # rule 1
    candidates, weakness = unpinch_candidates(clean, edges, options)
    edge_rounds = EDGE_ROUNDS if options.unpinch == "edge" else 0
    stats = {"n_candidates": int(is_new.sum()), "n_pruned": 0, "n_detached": 0,
             "n_unpinched": 0, "n_unpinch_edges": 0, "n_fallbacks": 0, "rounds": 0}
    alive = alive & ~(is_new & ~finite)
    stats["n_pruned"] += int((is_new & ~finite).sum())
    orders = None
    while True:
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        edges, alive, pruned, detached = _prune(edges, alive, is_new, n_boundary)
        stats["n_pruned"] += pruned
        stats["n_detached"] += detached
        orders = _match(clean, edges, n_boundary, loop_next, loop_prev, options, orders)
        stats["n_fallbacks"] += orders.n_fallbacks
        stats["rounds"] += 1
        indices, face_offsets = _orbits(orders, n_boundary, loop_next)
        if stats["rounds"] <= edge_rounds:
            drop = pinched_face_edges(indices, face_offsets, n, candidates, weakness)
            if drop.size:
                gone = np.isin(edge_keys(edges, n), drop)
                stats["n_unpinch_edges"] += int(gone.sum())
                edges = edges[~gone]
                continue
        degree = np.diff(orders.offsets)
        remove, stuck = _pinched_new_vertices(
            indices, face_offsets, degree, is_new,
            every=max(0, stats["rounds"] - edge_rounds) > GENTLE_ROUNDS)
        if stuck:
            remove = np.flatnonzero(is_new & alive)
        if remove.size == 0:
            break
        alive[remove] = False
        stats["n_unpinched"] += int(remove.size)
    degree = np.bincount(edges.reshape(-1), minlength=n)
    loop_id = _loop_ids(loop_next)
    has_new = np.zeros(loop_id.max() + 1 if n_boundary else 0, dtype=bool)
    has_new[loop_id[degree[:n_boundary] > 0]] = True
    stats["polygon_loops"] = int((~has_new).sum())
    stats["n_edges"] = len(edges)
    return Fill(indices, face_offsets, alive[n_boundary:] & (degree[n_boundary:] > 0), edges,
                stats)


def _loop_ids(loop_next: IntArray) -> IntArray:
    """(B,) which loop each boundary vertex is on."""
    n = len(loop_next)
    return component_labels(n, np.stack([np.arange(n), loop_next], axis=1))[1]


# ---------------------------------------------------------------------- assembly
@dataclass(frozen=True)
class Spliced:
    """The repaired mesh and where its parts came from.

    Attributes
    ----------
    mesh : PolygonMesh
        Kept vertices (in input order), then the new vertices; kept faces (in input
        order, each exactly as in the input up to vertex renumbering), then the new faces.
    vertex_map : (V,) int64
        Output index of each input vertex, -1 for removed vertices.
    face_source : (F_out,) int64
        Input index of each output face, -1 for new faces.
    n_new_vertices, n_new_faces : int
    """

    mesh: PolygonMesh
    vertex_map: IntArray
    face_source: IntArray
    n_new_vertices: int
    n_new_faces: int


def splice(cut: Cut, new_positions: FloatArray, fill: Fill) -> Spliced:
    """Put the kept faces and the fill together into one mesh.

    Parameters
    ----------
    cut : Cut
    new_positions : (M, 3) float
        Positions of the new vertices in the mesh's frame (all ``M`` candidates).
    fill : Fill
        From :func:`fill_hole` over the same ``M`` candidates.

    Returns
    -------
    Spliced
    """
    mesh = cut.mesh
    keep = cut.kept_vertex_mask()
    vertex_map = np.full(mesh.n_vertices, -1, dtype=np.int64)
    vertex_map[keep] = np.arange(int(keep.sum()))
    n_kept = int(keep.sum())
    used_new = np.flatnonzero(fill.new_alive)
    n_b = len(cut.boundary)
    local_map = np.full(n_b + len(fill.new_alive), -1, dtype=np.int64)
    local_map[:n_b] = vertex_map[cut.boundary]
    local_map[n_b + used_new] = n_kept + np.arange(len(used_new))
    kept_faces = cut.kept_faces
    corner_kept = ~cut.region[mesh.face_of_corner]
    indices = np.concatenate([vertex_map[mesh.face_indices[corner_kept]],
                              local_map[fill.face_indices]])
    sizes = np.concatenate([mesh.face_sizes[kept_faces], np.diff(fill.face_offsets)])
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    vertices = np.concatenate([mesh.vertices[keep],
                               np.asarray(new_positions, np.float64).reshape(-1, 3)[used_new]])
    source = np.concatenate([kept_faces, np.full(fill.n_faces, -1, dtype=np.int64)])
    return Spliced(PolygonMesh(vertices, indices, offsets), vertex_map, source,
                   len(used_new), fill.n_faces)
