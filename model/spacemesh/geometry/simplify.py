"""Simplification: a dense decode reduced by edge collapses to the size asked for.

The connectivity network joins near-uniform vertex sets well, and a compact mesh needs an
anisotropic one (few vertices on flat parts, many at creases), which it cannot join
(docs/GEOMETRY.md, "Compact meshes"). So the pipeline can decode densely and then
collapse edges (:func:`simplify`), cheapest first, where the cost is a quadric error
built from the **input points**: every point adds the plane through it with its normal
(estimated from its neighbours when the upload has none) to the quadric of the vertex
nearest to it, so a vertex that covers points on both sides of a crease stays on the
crease. A small share of the mesh's own face planes keeps the cost defined where a vertex
covers no point.

Every collapse keeps what the decode guaranteed, and more:

* **a closed oriented manifold**: the link condition (the two ends of the edge share
  exactly the two vertices opposite it), and no piece falls below a tetrahedron; the
  faces around the merged vertex keep their cyclic order, so their orientation;
* **no flipped face**: each face that moves keeps its normal within
  :attr:`SimplifyOptions.max_turn_cosine` of where it was, and a non-zero area;
* **no new crossing**: the faces around the merged vertex are tested exactly against
  every face near them (:func:`spacemesh.geometry.intersections.pairs_cross`);
* **the same pieces and genus**: edge collapses under the link condition keep both; the
  result is checked, and the input returned unchanged if it ever differs;
* **the same boundary**: on an open mesh no edge that touches a boundary vertex
  collapses (the link condition above is the one of a closed surface).

It stops at a vertex count (``target_vertices``, the dense decode's use), at an error
(``max_error``, ``face_type=polygons``: :func:`spacemesh.geometry.polygons.collapse_flat`)
or at a distance (``max_distance``, ``tolerance``), whichever comes first. With
``max_distance`` the mean distance from the points to the collapsed mesh is measured
every :data:`DISTANCE_EVERY` collapses, and the last mesh within it is returned; no
single collapse may then cost more than :data:`LOCAL_DISTANCE_SHARE` times it (its
``max_error``, unless given), so a small feature is not cut away because the mean
hides it. With ``max_error`` the error of a collapse is its quadric's cost
per unit of its weight (the trace of its 3x3 block): the weighted mean squared distance
of the merged vertex from the planes its quadric has gathered (the points', or with no
points the mesh's own faces'), so a collapse in a flat region costs about nothing, one
that cuts a crease or a curve does not; the cheapest first, none over ``max_error``, and
where the cheapest position would fold a face the other candidate positions within
``max_error`` are tried.

The result's faces are the decode's faces reduced by collapses: no face is made from the
points. numpy, scipy and a heap only.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.cancel import checkpoint
from spacemesh.geometry.fitting import plane_fits
from spacemesh.geometry.intersections import TOUCHING_SHARE, pairs_cross, touching_eps
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangle_normals, unique_edges, unit_rows
from spacemesh.primitives.closest import mean_distance
from spacemesh.topology import edge_connected_faces, surface_topology
from spacemesh.typed import FloatArray, IntArray

#: Collapses between two cancellation checkpoints (spacemesh.cancel).
CHECK_EVERY = 32
#: With ``max_distance``: collapses between two measurements of the mean distance from
#: the points to the mesh.
DISTANCE_EVERY = 16
#: With ``max_distance`` (and no ``max_error``): a collapse's error may be at most this
#: many times it (root mean square over the points its quadric gathered).
LOCAL_DISTANCE_SHARE = 3.0
#: A quadric's 3x3 block is solved for its minimum only when its determinant exceeds this
#: share of its trace cubed (else the ends and the midpoint are compared).
WELL_POSED = 1e-9


@dataclass(frozen=True)
class SimplifyOptions:
    """How :func:`simplify` weighs and checks its collapses.

    Attributes
    ----------
    face_weight : float
        Weight of the mesh's own face planes (area-weighted, per unit of the mean point
        weight) in each vertex's quadric: a regulariser where a vertex covers no point.
    max_turn_cosine : float
        A face may turn by at most this much: its new unit normal's dot product with
        its old one must exceed it.
    min_area_ratio : float
        A face's new area must exceed this share of the mean face area of the input.
    """

    face_weight: float = 0.05
    max_turn_cosine: float = 0.2
    min_area_ratio: float = 1e-3


@dataclass
class SimplifyResult:
    """The simplified mesh and what :func:`simplify` did.

    Attributes
    ----------
    mesh : PolygonMesh
        A triangle mesh (the input's triangles reduced by collapses).
    stats : dict
        ``collapsed`` (edges collapsed), ``refused`` (counts by reason: ``link``,
        ``piece``, ``flip``, ``crossing``), ``max_error`` (the largest collapse cost, a
        squared distance; per unit of weight with :func:`simplify`'s ``max_error``),
        ``kept_topology`` (False when the check failed and the input came back).
    vertex_map : (V_in,) int, optional
        The output vertex each input vertex was merged into (None when the input came
        back unchanged): every output face is an input face with its vertices mapped.
    """

    mesh: PolygonMesh
    stats: dict[str, Any]
    vertex_map: IntArray | None = None


def point_quadrics(vertices: FloatArray, points: FloatArray,
                   normals: FloatArray | None = None) -> FloatArray:
    """The quadric ``(V, 4, 4)`` of each vertex: the planes of the points nearest to it.

    Parameters
    ----------
    vertices : (V, 3) float
    points : (P, 3) float
    normals : (P, 3) float, optional
        The points' normals (unit or not; their sign does not matter); estimated from
        each point's neighbours (:func:`spacemesh.geometry.fitting.plane_fits`) when None.

    Returns
    -------
    (V, 4, 4) float64
        ``sum p p^T`` over the vertex's points, ``p = (n, -n . x)`` with unit ``n``:
        ``[v, 1] Q [v, 1]^T`` is the sum of squared distances from ``v`` to their planes.
    """
    points = np.asarray(points, dtype=np.float64)
    if normals is None:
        normals = plane_fits(points)[0]
    n = unit_rows(np.asarray(normals, dtype=np.float64))
    planes = np.concatenate([n, -np.einsum("pd,pd->p", n, points)[:, None]], axis=1)  # (P, 4)
    _, owner = cKDTree(vertices).query(points)  # (P,)
    quadrics = np.zeros((len(vertices), 4, 4))
    np.add.at(quadrics, owner, planes[:, :, None] * planes[:, None, :])
    return quadrics


def face_quadrics(vertices: FloatArray, triangles: IntArray) -> FloatArray:
    """Area-weighted face-plane quadrics ``(V, 4, 4)`` summed at each face's corners."""
    corners = vertices[triangles]  # (T, 3, 3)
    cross = triangle_normals(corners)  # (T, 3), twice the areas long
    double_area = np.linalg.norm(cross, axis=1)
    n = cross / np.maximum(double_area, 1e-300)[:, None]
    planes = np.concatenate([n, -np.einsum("td,td->t", n, corners[:, 0])[:, None]], axis=1)
    each = 0.5 * double_area[:, None, None] * planes[:, :, None] * planes[:, None, :]
    quadrics = np.zeros((len(vertices), 4, 4))
    for k in range(3):
        np.add.at(quadrics, triangles[:, k], each)
    return quadrics


def _placement(quadric: FloatArray, a: FloatArray, b: FloatArray
               ) -> tuple[float, FloatArray]:
    """The cost and position that minimise ``quadric`` for the edge ``a``-``b``: the
    quadric's own minimum when it is well posed and near the edge, else the best of the
    ends and the midpoint."""
    costs, h = _candidates(quadric, a, b)
    best = int(np.argmin(costs))
    return max(float(costs[best]), 0.0), h[best, :3]


def _candidates(quadric: FloatArray, a: FloatArray, b: FloatArray
                ) -> tuple[FloatArray, FloatArray]:
    """The costs ``(C,)`` of the edge ``a``-``b``'s candidate positions ``(C, 4)``
    (homogeneous): its ends, its midpoint and, when well posed and near the edge, the
    quadric's own minimum."""
    return _edge_candidates(quadric[None], a[None], b[None])[0]


def _edge_candidates(quadrics: FloatArray, a: FloatArray, b: FloatArray
                     ) -> list[tuple[FloatArray, FloatArray]]:
    """:func:`_candidates` of ``E`` edges at once: ``quadrics`` ``(E, 4, 4)``, ends
    ``a``, ``b`` ``(E, 3)``; the 3x3 solves are made together, every number as one edge
    alone would have it."""
    middle = 0.5 * (a + b)  # (E, 3)
    blocks = quadrics[:, :3, :3]  # (E, 3, 3)
    scales = (blocks[:, 0, 0] + blocks[:, 1, 1] + blocks[:, 2, 2]).tolist()
    dets = np.linalg.det(blocks).tolist()  # (E,)
    posed = np.array([scale > 0 and abs(det) > WELL_POSED * scale**3
                      for scale, det in zip(scales, dets, strict=True)], dtype=bool).reshape(-1)
    rows = np.flatnonzero(posed)
    near = np.zeros(len(a), dtype=bool)
    optima = np.zeros_like(a)  # (E, 3)
    if len(rows):
        optima[rows] = np.linalg.solve(blocks[rows], -quadrics[rows, :3, 3, None])[:, :, 0]
        # the optimum is used only near the edge: a far one is an ill-posed quadric
        near[rows] = (np.sum((optima[rows] - middle[rows]) ** 2, axis=1)
                      <= np.sum((a[rows] - b[rows]) ** 2, axis=1))
    out: list[tuple[FloatArray, FloatArray]] = []
    for e in range(len(a)):
        h = np.ones((4 if near[e] else 3, 4))
        h[0, :3], h[1, :3], h[2, :3] = a[e], b[e], middle[e]
        if near[e]:
            h[3, :3] = optima[e]
        out.append((np.einsum("ci,ij,cj->c", h, quadrics[e], h), h))
    return out


def _weight(quadric: FloatArray) -> float:
    """A quadric's weight, the trace of its 3x3 block (at least 1e-300): a cost over it
    is a mean squared distance (``max_error``'s unit, see the module docstring)."""
    return max(float(np.trace(quadric[:3, :3])), 1e-300)


class _Collapse(NamedTuple):
    """A collapse that passed its checks: where the merged vertex goes, the two faces
    that go away, and the faces around it (indices) with their new corners."""

    position: FloatArray  # (3,)
    shared: set[int]
    moved: list[int]
    new: IntArray  # (K, 3)


class _Collapser:
    """The mutable state of one simplification (see :func:`simplify`)."""

    def __init__(self, vertices: FloatArray, triangles: IntArray, quadrics: FloatArray,
                 options: SimplifyOptions, max_error: float | None = None) -> None:
        # with max_error: costs per unit of quadric weight, and every candidate position
        # within it tried (the cheapest may fold a fan that another keeps flat)
        self.max_error = max_error
        self.positions = vertices.copy()
        self.triangles = triangles.copy()
        self.quadrics = quadrics
        self.options = options
        self.face_alive = np.ones(len(triangles), dtype=bool)
        # each face's bounding box, kept up to date for the faces a collapse moves
        corners = vertices[triangles]  # (T, 3, 3)
        self.box_low, self.box_high = corners.min(axis=1), corners.max(axis=1)  # (T, 3)
        self.vertex_alive = np.ones(len(vertices), dtype=bool)
        self.version = np.zeros(len(vertices), dtype=np.int64)
        self.faces_of: list[set[int]] = [set() for _ in range(len(vertices))]
        for f, face in enumerate(triangles):
            for v in face:
                self.faces_of[int(v)].add(f)
        areas = 0.5 * np.linalg.norm(triangle_normals(vertices[triangles]), axis=1)
        self.min_area = options.min_area_ratio * float(areas.mean()) if len(areas) else 0.0
        # the boxes' margin: no pair touches farther apart (intersections.pairs_cross)
        self.eps = touching_eps(vertices, triangles) if len(triangles) else TOUCHING_SHARE
        # piece of each vertex and the vertices left in each piece
        _, face_piece = edge_connected_faces(PolygonMesh(
            vertices, triangles.reshape(-1), np.arange(0, 3 * len(triangles) + 1, 3)))
        self.piece = np.zeros(len(vertices), dtype=np.int64)
        self.piece[triangles.reshape(-1)] = np.repeat(face_piece, 3)
        self.piece_size = np.bincount(self.piece, minlength=int(self.piece.max()) + 1)
        self.refused = {"link": 0, "piece": 0, "flip": 0, "crossing": 0}
        self.heap: list[tuple[float, int, int, int, int]] = []
        self.parked: list[set[int]] = [set() for _ in range(len(vertices))]
        self.merged_into = np.arange(len(vertices))
        # the vertices of edges with one face (none on a closed mesh) never move
        unique, count = unique_edges(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2),
                                     len(vertices), return_counts=True)
        self.boundary = np.zeros(len(vertices), dtype=bool)
        self.boundary[unique[count == 1].reshape(-1)] = True

    def neighbours(self, v: int) -> set[int]:
        """The vertices that share a face with ``v``."""
        out = set(self.triangles[list(self.faces_of[v])].reshape(-1).tolist())
        out.discard(v)
        return out

    def push(self, edges: list[tuple[int, int]]) -> None:
        """Queue the collapses of ``edges`` (``a``-``b`` pairs) at their current costs."""
        if not edges:
            return
        ends = np.array(edges, dtype=np.int64).reshape(-1, 2)  # (E, 2)
        quadrics = self.quadrics[ends[:, 0]] + self.quadrics[ends[:, 1]]  # (E, 4, 4)
        candidates = _edge_candidates(quadrics, self.positions[ends[:, 0]],
                                      self.positions[ends[:, 1]])
        for (a, b), quadric, (costs, _) in zip(edges, quadrics, candidates, strict=True):
            cost = max(float(costs[int(np.argmin(costs))]), 0.0)
            if self.max_error is not None:
                cost /= _weight(quadric)
            lo, hi = min(a, b), max(a, b)
            heapq.heappush(self.heap,
                           (cost, lo, hi, int(self.version[lo]), int(self.version[hi])))

    def try_collapse(self, a: int, b: int) -> bool:
        """Collapse ``b`` into ``a`` if every check passes (module docstring); a refused
        edge is parked and queued again when a collapse next to it changes its
        surroundings."""
        plan = self._plan(a, b)
        if isinstance(plan, str):  # refused, and why
            self.refused[plan] += 1
            self.parked[a].add(b)
            self.parked[b].add(a)
            return False
        self.positions[a] = plan.position
        self.quadrics[a] = self.quadrics[a] + self.quadrics[b]
        self.triangles[plan.moved] = plan.new
        corners = self.positions[plan.new]  # (K, 3, 3)
        self.box_low[plan.moved] = corners.min(axis=1)
        self.box_high[plan.moved] = corners.max(axis=1)
        for f in plan.shared:
            self.face_alive[f] = False
            for u in self.triangles[f]:
                self.faces_of[int(u)].discard(f)
        self.faces_of[a] |= self.faces_of[b]
        self.faces_of[b] = set()
        self.vertex_alive[b] = False
        self.merged_into[b] = a
        self.piece_size[self.piece[a]] -= 1
        self.version[a] += 1
        self.version[b] += 1
        ring = self.neighbours(a)
        edges = [(a, u) for u in ring]  # the edges of the merged vertex, at their new costs
        for u in ring | {a, b}:  # edges refused near here may pass now
            edges += [(u, w) for w in self.parked[u] if self.vertex_alive[u]
                      and self.vertex_alive[w] and w not in ring | {a}]
            self.parked[u] = set()
        self.push(edges)
        return True

    def _plan(self, a: int, b: int) -> str | _Collapse:
        """The collapse of ``b`` into ``a`` if it passes every check, else why not
        (``link``, ``piece``, ``flip`` or ``crossing``)."""
        shared = self.faces_of[a] & self.faces_of[b]
        if len(shared) != 2 or self.boundary[a] or self.boundary[b]:
            return "link"
        opposite = {int(u) for f in shared for u in self.triangles[f]} - {a, b}
        if self.neighbours(a) & self.neighbours(b) != opposite:
            return "link"
        if self.piece_size[self.piece[a]] <= 4:
            return "piece"
        quadric = self.quadrics[a] + self.quadrics[b]
        if self.max_error is None:
            positions = [_placement(quadric, self.positions[a], self.positions[b])[1]]
        else:  # every candidate within the error, the cheapest first
            costs, h = _candidates(quadric, self.positions[a], self.positions[b])
            costs /= _weight(quadric)
            order = np.argsort(costs, kind="stable")
            positions = [h[c, :3] for c in order[:1]] + [
                h[c, :3] for c in order[1:] if costs[c] <= self.max_error]
        moved = sorted((self.faces_of[a] | self.faces_of[b]) - shared)  # the new fan
        old = self.triangles[moved]  # (K, 3)
        new = np.where(old == b, a, old)
        unit_old = unit_rows(triangle_normals(self.positions[old]))  # (K, 3)
        why = "flip"
        for position in positions:
            new_corners = self.positions[new]
            new_corners[new == a] = position
            if not self._keeps_orientation(unit_old, new_corners):
                continue
            if self._crosses(moved, new, a, position, shared):
                why = "crossing"
                continue
            return _Collapse(position, shared, moved, new)
        return why

    def _keeps_orientation(self, unit_old: FloatArray, new: FloatArray) -> bool:
        """Whether no face of the fan (unit normals ``unit_old`` ``(K, 3)``, new corners
        ``new`` ``(K, 3, 3)``) turns by more than the options allow or shrinks below the
        smallest area."""
        n_new = triangle_normals(new)
        area_new = 0.5 * np.linalg.norm(n_new, axis=1)
        if np.any(area_new <= self.min_area):
            return False
        unit_new = n_new / np.maximum(2 * area_new[:, None], 1e-300)
        return bool(np.all(np.einsum("kd,kd->k", unit_old, unit_new)
                           > self.options.max_turn_cosine))

    def _crosses(self, moved: list[int], new: IntArray, a: int, position: FloatArray,
                 removed: set[int]) -> bool:
        """Whether a face of the new fan ``new`` (``(K, 3)``, vertex ``a`` at
        ``position``) would intersect another face near it, or another face of the fan.

        The faces near it are the live ones whose bounding box (kept up to date by
        :meth:`try_collapse`) meets the fan's, each pair is tested only when their boxes
        meet (``eps`` apart), and the test is :func:`pairs_cross` of the mesh with ``a``
        moved."""
        fan = self.positions[new]  # (K, 3, 3)
        fan[new == a] = position
        fan_low, fan_high = fan.min(axis=1), fan.max(axis=1)  # (K, 3)
        lo = fan_low.min(axis=0) - self.eps
        hi = fan_high.max(axis=0) + self.eps
        near = (self.face_alive & np.all(self.box_high >= lo, axis=1)
                & np.all(self.box_low <= hi, axis=1))  # (T,)
        near[moved] = False
        near[list(removed)] = False
        others = np.flatnonzero(near)  # (O,)
        k = len(moved)
        low = np.concatenate([fan_low, self.box_low[others]]) - self.eps  # (K + O, 3)
        high = np.concatenate([fan_high, self.box_high[others]]) + self.eps
        i_fan, j_fan = np.triu_indices(k, 1)
        i = np.concatenate([i_fan, np.repeat(np.arange(k), len(others))])
        j = np.concatenate([j_fan, k + np.tile(np.arange(len(others)), k)])
        # only pairs whose bounding boxes overlap can meet
        overlap = np.all((high[i] >= low[j]) & (high[j] >= low[i]), axis=1)
        i, j = i[overlap], j[overlap]
        if len(i) == 0:
            return False
        moved_positions = self.positions.copy()  # (V, 3)
        moved_positions[a] = position
        local = np.concatenate([new, self.triangles[others]])  # (K + O, 3)
        return bool(pairs_cross(moved_positions, local, i, j).any())

    def mesh(self) -> tuple[PolygonMesh, IntArray]:
        """The current mesh, its vertices renumbered in their old order, and the output
        vertex of every input vertex."""
        keep = np.flatnonzero(self.vertex_alive)
        index = np.full(len(self.positions), -1, dtype=np.int64)
        index[keep] = np.arange(len(keep))
        tri = index[self.triangles[self.face_alive]]
        root = self.merged_into.copy()
        while True:  # follow chains of merges to the surviving vertex
            deeper = root[root]
            if np.array_equal(deeper, root):
                break
            root = deeper
        mesh = PolygonMesh(self.positions[keep], tri.reshape(-1),
                           np.arange(0, 3 * len(tri) + 1, 3))
        return mesh, index[root]

    def mean_distance(self, points: FloatArray) -> float:
        """The mean distance from ``points`` to the current mesh."""
        return mean_distance(points, self.positions, self.triangles[self.face_alive])


def simplify(mesh: PolygonMesh, points: FloatArray | None, normals: FloatArray | None = None, *,
             target_vertices: int = 4, options: SimplifyOptions | None = None,
             max_error: float | None = None, max_distance: float | None = None
             ) -> SimplifyResult:
    """Collapse edges of a closed triangle mesh, cheapest first, down to
    ``target_vertices``, up to ``max_error`` or up to ``max_distance`` (see the module
    docstring).

    Parameters
    ----------
    mesh : PolygonMesh
        A closed oriented manifold triangle mesh (a decode), in the points' frame.
    points : (P, 3) float, optional
        The input points whose planes make the cost; None: the mesh's own face planes
        alone make it (area-weighted), so the cost measures how far a collapse moves
        the surface from where the mesh has it.
    normals : (P, 3) float, optional
        Their normals (estimated when None).
    target_vertices : int
        Collapse until this many vertices are left, or no collapse passes its checks.
        The default (4) leaves ``max_error`` the stop.
    options : SimplifyOptions, optional
    max_error : float, optional
        Make no collapse whose error (its cost per unit of quadric weight, a mean
        squared distance: the module docstring) exceeds this; None: costs are summed
        squared distances and only ``target_vertices`` stops.
    max_distance : float, optional
        Stop before the mean distance from ``points`` to the mesh exceeds this (measured
        every :data:`DISTANCE_EVERY` collapses; the last mesh within it is returned, the
        input when none was); ``max_error`` defaults to
        ``(LOCAL_DISTANCE_SHARE * max_distance) ** 2``. Needs ``points``.

    Returns
    -------
    SimplifyResult
        The input unchanged when it is not a triangle mesh or already small enough.
    """
    options = options or SimplifyOptions()
    if max_distance is not None:
        if points is None:
            raise ValueError("max_distance needs the points")
        if max_error is None:
            max_error = (LOCAL_DISTANCE_SHARE * max_distance) ** 2
    stats: dict[str, Any] = {"collapsed": 0, "refused": {}, "max_error": 0.0,
                             "kept_topology": True}
    if (not mesh.is_triangle_mesh() or mesh.n_vertices <= target_vertices
            or mesh.n_faces == 0 or (points is not None and len(points) < 4)):
        return SimplifyResult(mesh, stats)
    vertices = mesh.vertices.astype(np.float64)
    triangles = mesh.face_indices.reshape(-1, 3).astype(np.int64)
    faces = face_quadrics(vertices, triangles)
    if points is None:  # the surface where it is
        quadrics = faces
    else:
        quadrics = point_quadrics(vertices, points, normals)
        mean_weight = float(np.trace(quadrics[:, :3, :3], axis1=1, axis2=2).sum()) / max(
            float(np.trace(faces[:, :3, :3], axis1=1, axis2=2).sum()), 1e-300)
        quadrics += options.face_weight * mean_weight * faces
    state = _Collapser(vertices, triangles, quadrics, options, max_error)
    state.push([(int(a), int(b)) for a, b in mesh.edges])
    alive = mesh.n_vertices
    within: tuple[PolygonMesh, IntArray | None, dict[str, Any]] = (mesh, None, dict(stats))
    while alive > target_vertices and state.heap:
        if stats["collapsed"] % CHECK_EVERY == 0:
            checkpoint()  # abandoned work stops here (spacemesh.cancel)
        cost, a, b, version_a, version_b = heapq.heappop(state.heap)
        if (not state.vertex_alive[a] or not state.vertex_alive[b]
                or state.version[a] != version_a or state.version[b] != version_b):
            continue
        if max_error is not None and cost > max_error:
            break  # the cheapest collapse left would move the surface too far
        if state.try_collapse(a, b):
            alive -= 1
            stats["collapsed"] += 1
            stats["max_error"] = max(stats["max_error"], cost)
            if max_distance is not None and stats["collapsed"] % DISTANCE_EVERY == 0:
                if not _within(state, points, max_distance, stats, within):
                    break
                within = (*state.mesh(), dict(stats))
    stats["refused"] = dict(state.refused)
    if max_distance is not None and (stats.get("stopped_at_distance") or not _within(
            state, points, max_distance, stats, within)):
        out, vertex_map, kept = within  # the last mesh within the distance
        stats.update(collapsed=kept["collapsed"], max_error=kept["max_error"])
        if vertex_map is None:
            return SimplifyResult(mesh, stats)
    else:
        out, vertex_map = state.mesh()
    before, after = surface_topology(mesh), surface_topology(out)
    if (before.pieces, before.genus) != (after.pieces, after.genus):
        stats["kept_topology"] = False
        return SimplifyResult(mesh, stats)
    return SimplifyResult(out, stats, vertex_map)


def _within(state: _Collapser, points: FloatArray | None, max_distance: float,
            stats: dict[str, Any], last: tuple[PolygonMesh, IntArray | None, dict[str, Any]]
            ) -> bool:
    """Whether the mean distance from ``points`` to ``state``'s mesh is within
    ``max_distance``; ``stats["mean_distance"]`` is the measurement (``last``'s, the mesh
    kept, when it is not)."""
    assert points is not None
    distance = state.mean_distance(points)
    if distance <= max_distance:
        stats["mean_distance"] = distance
        return True
    stats["mean_distance"] = last[2].get("mean_distance")
    stats["stopped_at_distance"] = True
    return False


__all__ = ["SimplifyOptions", "SimplifyResult", "face_quadrics", "point_quadrics",
           "simplify"]
