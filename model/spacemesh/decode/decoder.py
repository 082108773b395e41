"""Decoding: per-vertex embeddings to an oriented manifold polygon mesh (paper Sec. 3).

The guarantee: :func:`decode` turns ANY finite or non-finite embedding into a valid
halfedge mesh: twin is an involution without fixed points, ``next`` is a permutation,
every face has at least three distinct vertices, and every vertex has one fan of faces.
It follows from construction plus three rules, applied until nothing changes:

1. Vertices with degree 0 or 1 are removed (with their edge). A degree-1 vertex would
   need ``next`` to map its only incoming halfedge to its own twin: a two-sided face.
   With every degree at least 2 and one cyclic order per vertex, a face of one or two
   sides is impossible, so no two-sided orbit survives.
2. Degree-2 vertices are kept: they lie on two faces, one on each side.
3. A face that visits a vertex twice (a pinched polygon) loses its weakest edge at a
   repeated vertex: of the face's edges that touch a vertex it repeats, the one whose
   embedding distance is largest (closest to the threshold). A wrong edge (a false
   positive of the threshold) is what usually pinches a face, and it is usually a weak
   one. The two neighbourhoods are matched again. After ``EDGE_ROUNDS`` such rounds
   (or from the start with ``DecodeOptions(unpinch="vertex")``) a pinched face instead
   loses one of the vertices it repeats (the one of highest degree, then lowest index)
   with its edges; after ``GENTLE_ROUNDS`` of those (only pathological embeddings get
   there) every repeated vertex is removed at once.

Each round removes at least one edge or vertex, so decoding terminates; in the worst
case (an adversarial embedding) the result is the empty mesh, which is valid. Non-finite
embedding entries are treated as "no edge" for that vertex. See docs/REPRESENTATION.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from spacemesh.angular import oriented_angular_cycles
from spacemesh.cancel import checkpoint
from spacemesh.connectivity import Connectivity, csr_from_edges
from spacemesh.decode.crossing import uncrossed
from spacemesh.decode.refinement import flip_diagonals, reinsert_vertices
from spacemesh.decode.splitting import split_long_faces
from spacemesh.matching import FallbackFn, greedy_single_cycle, match_cycles
from spacemesh.mesh import PolygonMesh
from spacemesh.permutation import (
    SINKHORN_ITERS,
    Reduction,
    group_by_degree,
    neighbourhood_log_phi_bar,
)
from spacemesh.primitives import edge_keys
from spacemesh.spacetime import (
    Distance,
    distance_operands,
    edges_below_threshold,
    operand_distances,
)
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Rounds of one-edge-per-pinched-face removal before the vertex rule takes over.
EDGE_ROUNDS = 30
#: Rounds of one-vertex-per-face removal before every repeated vertex goes at once.
GENTLE_ROUNDS = 12
#: Fallbacks for a vertex whose optimal assignment is not a single orbit.
Fallback = Literal["angular", "greedy"]
#: What a pinched face loses first: its weakest edge, or one of its repeated vertices.
Unpinch = Literal["edge", "vertex"]

#: Degree bound applied while decoding arbitrary embeddings (see edges_below_threshold).
MAX_DEGREE = 64


@dataclass(frozen=True)
class Embeddings:
    """The SpaceMesh embeddings of ``N`` vertices.

    Parameters
    ----------
    adjacency : (N, k) float
        Adjacency embeddings ``x``.
    tau : float
        Edge threshold.
    root, prev, next : (N, kp) float
        Permutation embeddings.
    """

    adjacency: FloatArray
    tau: float
    root: FloatArray
    prev: FloatArray
    next: FloatArray

    @property
    def n_vertices(self) -> int:
        """Number of vertices ``N``."""
        return len(self.adjacency)


@dataclass(frozen=True)
class DecodeOptions:
    """How embeddings are read: distance, reduction, Sinkhorn iterations, degree bound,
    and the fallback for a vertex whose optimal assignment is not one orbit: ``angular``
    (its neighbours by angle, in the direction ``Phi_bar`` prefers; needs positions) or
    ``greedy`` (the paper's greedy single orbit, used without positions), and what a
    pinched face loses first: its weakest ``edge`` (default) or a repeated ``vertex``
    (see the module docstring), and whether the weaker of two crossing quad diagonals
    is dropped before matching (``uncross``; needs positions, see
    :mod:`spacemesh.decode.crossing`), and the most sides a face may keep (``max_sides``: longer
    faces are cut along their strongest missing diagonals, see :mod:`spacemesh.decode.splitting`;
    3 for a model trained on triangle meshes, None keeps every polygon), and the
    refinement of the finished mesh (:mod:`spacemesh.decode.refinement`): ``reinsert`` puts
    removed vertices back into the triangles the network rates closest, ``flip`` turns
    triangle pairs to the diagonal the network rates closer, and
    ``flat_delaunay_degrees`` (needs positions) makes quads folded by less than that
    Delaunay instead, as the ``qem`` training meshes are, and ``fit_gain`` (needs the
    conditioning points) flips a quad to the diagonal whose triangles pass closer to
    the points by more than that fraction (a data-dependent triangulation)."""

    distance: Distance = "spacetime"
    n_space: int | None = None
    reduction: Reduction = "product"
    reduction_params: dict[str, FloatArray] | None = None
    sinkhorn_iters: int = SINKHORN_ITERS
    max_degree: int | None = MAX_DEGREE
    fallback: Fallback = "angular"
    unpinch: Unpinch = "edge"
    uncross: bool = True
    max_sides: int | None = None
    reinsert: bool = False
    flip: bool = False
    flat_delaunay_degrees: float | None = None
    fit_gain: float | None = None


@dataclass
class DecodeResult:
    """The decoded mesh and how it was obtained.

    Attributes
    ----------
    mesh : PolygonMesh
        The mesh over the vertices that survived (only vertices used by faces).
    vertex_ids : (V',) int64
        Input index of each output vertex.
    connectivity : Connectivity
        Edges and cyclic orders over the input indices (removed vertices have degree 0).
    n_fallbacks : int
        Vertices whose optimal assignment was not a single orbit (greedy fallback).
    n_pruned : int
        Vertices removed for degree below 2 (isolated vertices included).
    n_unpinched : int
        Vertices removed because a face visited them twice.
    n_unpinch_edges : int
        Edges removed because a face visited one of their vertices twice.
    n_uncrossed : int
        Candidate edges dropped as the weaker of two crossing quad diagonals.
    n_split : int
        Diagonals added to faces longer than ``DecodeOptions.max_sides``.
    n_reinserted : int
        Removed vertices put back (``DecodeOptions.reinsert``).
    n_flipped : int
        Diagonals flipped (``DecodeOptions.flip``, ``flat_delaunay_degrees``).
    rounds : int
        Matching rounds (1 when no face was pinched).
    """

    mesh: PolygonMesh
    vertex_ids: IntArray
    connectivity: Connectivity
    n_fallbacks: int = 0
    n_pruned: int = 0
    n_unpinched: int = 0
    n_unpinch_edges: int = 0
    n_uncrossed: int = 0
    n_split: int = 0
    n_reinserted: int = 0
    n_flipped: int = 0
    rounds: int = 1
    stats: dict = field(default_factory=dict)


def _prune_low_degree(edges: IntArray, alive: BoolArray) -> tuple[IntArray, BoolArray, int]:
    """Remove vertices of degree < 2 until none is left; returns the kept edges."""
    n_removed = 0
    while True:
        keep = alive[edges[:, 0]] & alive[edges[:, 1]]
        edges = edges[keep]
        degree = np.bincount(edges.reshape(-1), minlength=len(alive))
        low = alive & (degree < 2)
        if not low.any():
            return edges, alive, n_removed
        alive = alive & ~low
        n_removed += int(low.sum())


def repeated_in_faces(
    indices: IntArray, offsets: IntArray, n_vertices: int
) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """The (face, vertex) pairs where a face visits a vertex more than once.

    Parameters
    ----------
    indices, offsets : CSR faces
    n_vertices : int

    Returns
    -------
    face : (S,) int64
        The face of each slot of ``indices``.
    repeated : (R,) int64
        Distinct keys ``face * n_vertices + vertex`` of the repeats.
    rep_face, rep_vertex : (R,) int64
        The same, split.
    """
    face = np.repeat(np.arange(len(offsets) - 1, dtype=np.int64), np.diff(offsets))
    key = np.sort(face * n_vertices + indices)
    repeated = np.unique(key[1:][key[1:] == key[:-1]])
    rep_face, rep_vertex = np.divmod(repeated, n_vertices)
    return face, repeated, rep_face, rep_vertex


def _pinched_vertices(
    indices: IntArray, offsets: IntArray, degree: IntArray, all_repeated: bool = False
) -> IntArray:
    """One vertex per pinched face: the repeated vertex of highest degree (then lowest index).

    Parameters
    ----------
    indices, offsets : CSR faces
    degree : (N,) int64
        Vertex degrees.
    all_repeated : bool
        Return every repeated vertex instead (the fast rule for pathological inputs).

    Returns
    -------
    (P,) int64
        Distinct vertices to remove.
    """
    _face, repeated, rep_face, rep_vertex = repeated_in_faces(indices, offsets, len(degree))
    if repeated.size == 0 or all_repeated:
        return np.unique(rep_vertex)
    # within each face: highest degree first, then lowest index
    order = np.lexsort((rep_vertex, -degree[rep_vertex], rep_face))
    first = np.concatenate([[True], rep_face[order][1:] != rep_face[order][:-1]])
    return np.unique(rep_vertex[order][first])


def pinched_face_edges(
    indices: IntArray, offsets: IntArray, n_vertices: int, removable_keys: IntArray,
    edge_distance: FloatArray,
) -> IntArray:
    """One edge per pinched face: of its removable edges that touch a vertex it repeats,
    the weakest (largest ``edge_distance``, then lowest key).

    Parameters
    ----------
    indices, offsets : CSR faces
    n_vertices : int
    removable_keys : (E,) int64
        Sorted keys ``i * N + j`` (``i < j``) of the removable edges; face sides that are
        not among them (the kept boundary of a repaired hole) are never chosen.
    edge_distance : (E,) float
        The weakness of each of those edges (:func:`unpinch_candidates`).

    Returns
    -------
    (P,) int64
        Distinct keys of the edges to remove (empty when no face is pinched, or no
        pinched face has a removable edge at its repeated vertex).
    """
    face, repeated, _, _ = repeated_in_faces(indices, offsets, n_vertices)
    if repeated.size == 0:
        return repeated
    following = np.arange(1, len(indices) + 1)  # slot of each face edge's second vertex
    wraps = following == offsets[1:][face]
    following[wraps] = offsets[:-1][face[wraps]]
    u, w = indices, indices[following]
    keys = edge_keys(np.stack([u, w], axis=1), n_vertices)
    at_repeat = np.isin(face * n_vertices + u, repeated) | np.isin(face * n_vertices + w,
                                                                   repeated)
    where = np.minimum(np.searchsorted(removable_keys, keys),
                       max(len(removable_keys) - 1, 0))
    removable = (removable_keys[where] == keys) if len(removable_keys) else np.zeros_like(at_repeat)
    slots = np.flatnonzero(at_repeat & removable)
    distance = edge_distance[where[slots]]
    order = np.lexsort((keys[slots], -distance, face[slots]))
    chosen = slots[order]
    first = np.concatenate([[True], face[chosen][1:] != face[chosen][:-1]])
    return np.unique(keys[chosen[first]])


def unpinch_candidates(
    emb: Embeddings, edges: IntArray, options: DecodeOptions
) -> tuple[IntArray, FloatArray]:
    """The edges a pinched face may lose, as :func:`pinched_face_edges` takes them.

    Parameters
    ----------
    emb : Embeddings
    edges : (E, 2) int64
        With ``i < j``.
    options : DecodeOptions
        Its distance and ``n_space``.

    Returns
    -------
    keys : (E,) int64
        The edges' keys (:func:`spacemesh.primitives.edge_keys`), sorted.
    weakness : (E,) float64
        The embedding distance of each edge, in the same order.
    """
    by_key = np.argsort(edge_keys(edges, emb.n_vertices))
    edges = edges[by_key]
    return edge_keys(edges, emb.n_vertices), edge_weakness(emb, edges, options)


def edge_weakness(emb: Embeddings, edges: IntArray, options: DecodeOptions) -> FloatArray:
    """Embedding distance ``(E,)`` of each of the ``(E, 2)`` edges (larger is weaker)."""
    operands = distance_operands(emb.adjacency, options.distance, options.n_space)
    return operand_distances(operands, edges[:, 0], edges[:, 1])


def _angular_fallback(
    positions: FloatArray, vertices: IntArray, neighbours: IntArray, log_phi_bar: FloatArray
) -> FallbackFn:
    """The ``angular`` fallback for one degree group (greedy where positions are not finite)."""

    def fallback(rows: IntArray) -> IntArray:
        nb = neighbours[rows]  # (R, d)
        finite = np.isfinite(positions[nb]).all(axis=(1, 2)) & np.isfinite(
            positions[vertices[rows]]
        ).all(axis=1)
        perms = np.empty(nb.shape, dtype=np.int64)
        if finite.any():
            perms[finite] = oriented_angular_cycles(
                positions, vertices[rows[finite]], nb[finite], log_phi_bar[rows[finite]]
            )
        for r in np.flatnonzero(~finite):
            cost = -np.exp(log_phi_bar[rows[r]])
            cost[np.diag_indices_from(cost)] = np.inf
            perms[r] = greedy_single_cycle(cost)
        return perms

    return fallback


def _match_all(
    emb: Embeddings,
    offsets: IntArray,
    neighbours: IntArray,
    todo: BoolArray,
    local: IntArray,
    options: DecodeOptions,
    positions: FloatArray | None = None,
) -> int:
    """Fill ``local`` (local successor per slot) for vertices flagged in ``todo``."""
    fallbacks = 0
    for degree, vertices in group_by_degree(offsets).items():
        vertices = vertices[todo[vertices]]
        if degree < 2 or vertices.size == 0:
            continue
        log_phi_bar = neighbourhood_log_phi_bar(
            emb.root,
            emb.prev,
            emb.next,
            vertices,
            offsets,
            neighbours,
            degree,
            options.reduction,
            options.reduction_params,
            options.sinkhorn_iters,
        )
        slots = offsets[vertices][:, None] + np.arange(degree)[None, :]  # (B, d)
        fallback = None
        if options.fallback == "angular" and positions is not None:
            fallback = _angular_fallback(positions, vertices, neighbours[slots], log_phi_bar)
        perms, n_fb = match_cycles(log_phi_bar, fallback)  # (B, d)
        local[slots] = perms
        fallbacks += n_fb
    return fallbacks


def _sanitise(emb: Embeddings, alive: BoolArray) -> tuple[Embeddings, BoolArray]:
    """Replace non-finite entries; vertices with non-finite adjacency take no part."""
    # numpy types all(axis=...) as bool | array; with an axis on a 2-D array it is an array
    finite: BoolArray = np.isfinite(emb.adjacency).all(axis=1)  # type: ignore[assignment]
    perm_finite = [
        np.nan_to_num(np.asarray(a, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        for a in (emb.root, emb.prev, emb.next)
    ]
    adjacency = np.where(finite[:, None], emb.adjacency, 0.0)
    tau = float(emb.tau) if np.isfinite(emb.tau) else -np.inf
    clean = Embeddings(adjacency, tau, *perm_finite)
    return clean, alive & finite


def _finished(
    connectivity: Connectivity, stats: dict, emb: Embeddings, options: DecodeOptions,
    took_part: BoolArray, positions: FloatArray | None, points: FloatArray | None,
) -> tuple[Connectivity, dict]:
    """The valid decode, with its long faces cut when ``options.max_sides`` is set, then
    refined (:mod:`spacemesh.decode.refinement`) as ``options`` asks."""
    stats["n_split"] = stats["n_reinserted"] = stats["n_flipped"] = 0
    fit = options.fit_gain is not None and points is not None
    refine = options.reinsert or options.flip or options.flat_delaunay_degrees is not None
    refine = refine or fit
    if options.max_sides is None and not refine:
        return connectivity, stats
    operands = distance_operands(emb.adjacency, options.distance, options.n_space)
    if options.max_sides is not None:
        connectivity, stats["n_split"] = split_long_faces(
            connectivity, operands, options.max_sides
        )
    if options.reinsert:
        removed = np.flatnonzero(took_part & (connectivity.degree == 0))
        connectivity, stats["n_reinserted"] = reinsert_vertices(connectivity, removed, operands,
                                                                  positions)
    if options.flip or options.flat_delaunay_degrees is not None or fit:
        connectivity, stats["n_flipped"] = flip_diagonals(
            connectivity, operands, positions, flat_degrees=options.flat_delaunay_degrees,
            by_score=options.flip, points=points, fit_gain=options.fit_gain,
        )
    return connectivity, stats


def decode_connectivity(
    emb: Embeddings,
    options: DecodeOptions | None = None,
    alive: BoolArray | None = None,
    positions: FloatArray | None = None,
    points: FloatArray | None = None,
) -> tuple[Connectivity, dict]:
    """Edges and single-orbit cyclic orders for the embeddings (see module docstring).

    Parameters
    ----------
    emb : Embeddings
    options : DecodeOptions, optional
    alive : (N,) bool, optional
        Vertices that take part (for example the diffusion's padding mask).
    positions : (N, 3) float, optional
        Vertex positions, for the ``angular`` fallback (greedy without them).
    points : (P, 3) float, optional
        The conditioning point cloud in the frame of ``positions``, for
        ``options.fit_gain``.

    Returns
    -------
    connectivity : Connectivity
        Over all ``N`` input indices; removed vertices have degree 0.
    stats : dict
        ``n_fallbacks``, ``n_pruned``, ``n_unpinched``, ``n_unpinch_edges``,
        ``n_uncrossed`` (crossing diagonals dropped), ``n_split`` (diagonals added to
        long faces), ``n_reinserted``, ``n_flipped`` (the refinement), ``rounds``.
    """
    options = options or DecodeOptions()
    n = emb.n_vertices
    alive = np.ones(n, dtype=bool) if alive is None else np.asarray(alive, dtype=bool).copy()
    emb, alive = _sanitise(emb, alive)
    took_part = alive.copy()
    edges = edges_below_threshold(
        emb.adjacency, emb.tau, options.distance, options.n_space, alive, options.max_degree
    )
    stats = {"n_fallbacks": 0, "n_pruned": 0, "n_unpinched": 0, "n_unpinch_edges": 0,
             "n_uncrossed": 0, "rounds": 0}
    if options.uncross and positions is not None and len(edges):
        keep = uncrossed(positions, edges, edge_weakness(emb, edges, options))
        stats["n_uncrossed"] = int((~keep).sum())
        edges = edges[keep]
    candidates, weakness = unpinch_candidates(emb, edges, options)
    edge_rounds = EDGE_ROUNDS if options.unpinch == "edge" else 0
    old_offsets = np.zeros(n + 1, dtype=np.int64)
    old_local = np.zeros(0, dtype=np.int64)
    dirty = np.ones(n, dtype=bool)
    while True:
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        edges, alive, pruned = _prune_low_degree(edges, alive)
        stats["n_pruned"] += pruned
        offsets, neighbours = csr_from_edges(edges, n)
        degree = np.diff(offsets)
        # neighbourhoods that changed since the last round are matched again
        dirty |= degree != np.diff(old_offsets)
        local = np.zeros(len(neighbours), dtype=np.int64)
        clean = np.flatnonzero(~dirty & (degree > 0))
        if clean.size:
            d = degree[clean]
            within = np.arange(d.sum()) - np.repeat(np.cumsum(d) - d, d)
            local[np.repeat(offsets[clean], d) + within] = old_local[
                np.repeat(old_offsets[clean], d) + within
            ]
        stats["n_fallbacks"] += _match_all(
            emb, offsets, neighbours, dirty, local, options, positions
        )
        stats["rounds"] += 1
        successor = np.repeat(offsets[:-1], degree) + local
        connectivity = Connectivity(n, offsets, neighbours, successor)
        indices, face_offsets = connectivity.faces()
        dirty = np.zeros(n, dtype=bool)
        if stats["rounds"] <= edge_rounds:
            drop = pinched_face_edges(indices, face_offsets, n, candidates, weakness)
            if drop.size == 0:
                return _finished(connectivity, stats, emb, options, took_part, positions, points)
            touched = np.isin(edge_keys(edges, n), drop)
            stats["n_unpinch_edges"] += int(touched.sum())
        else:
            pinched = _pinched_vertices(
                indices, face_offsets, degree,
                all_repeated=stats["rounds"] - edge_rounds > GENTLE_ROUNDS,
            )
            if pinched.size == 0:
                return _finished(connectivity, stats, emb, options, took_part, positions, points)
            alive[pinched] = False
            stats["n_unpinched"] += int(pinched.size)
            # numpy types any(axis=...) as bool | array; here it is an array
            touched = np.isin(edges, pinched).any(axis=1)  # type: ignore[assignment]
        dirty[edges[touched].reshape(-1)] = True
        edges = edges[~touched]
        old_offsets, old_local = offsets, local


def decode(
    positions: FloatArray,
    emb: Embeddings,
    options: DecodeOptions | None = None,
    alive: BoolArray | None = None,
    points: FloatArray | None = None,
) -> DecodeResult:
    """Decode embeddings into a valid oriented manifold polygon mesh.

    Parameters
    ----------
    positions : (N, 3) float
        Vertex positions.
    emb : Embeddings
        Adjacency and permutation embeddings of the same ``N`` vertices.
    options : DecodeOptions, optional
    alive : (N,) bool, optional
        Vertices that take part (padding mask).
    points : (P, 3) float, optional
        The conditioning point cloud, in the frame of ``positions``: with
        ``options.fit_gain``, the refinement flips diagonals toward it (non-finite rows
        are ignored).

    Returns
    -------
    DecodeResult
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    connectivity, stats = decode_connectivity(emb, options, alive, positions, points)
    full = connectivity.to_mesh(positions)
    mesh, kept = full.remove_unreferenced_vertices()
    return DecodeResult(
        mesh=mesh,
        vertex_ids=kept,
        connectivity=connectivity,
        n_fallbacks=stats["n_fallbacks"],
        n_pruned=stats["n_pruned"],
        n_unpinched=stats["n_unpinched"],
        n_unpinch_edges=stats["n_unpinch_edges"],
        n_uncrossed=stats["n_uncrossed"],
        n_split=stats["n_split"],
        n_reinserted=stats["n_reinserted"],
        n_flipped=stats["n_flipped"],
        rounds=stats["rounds"],
        stats=stats,
    )
