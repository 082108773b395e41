"""The decoded mesh refined: removed vertices put back, diagonals flipped.

After matching, pruning and unpinching, the decode is a valid mesh, but it may have lost
vertices (those it could not give one fan of faces) and it may disagree with the
network on a quad's diagonal (the threshold let only the weaker one through, or the
triangle cuts of :mod:`spacemesh.decode.splitting` chose it). Two local operations fix that
without leaving the space of closed oriented manifolds:

:func:`reinsert_vertices`
    Every vertex that took part but was removed goes back into the triangle whose
    corners the network rates closest to it (the smallest sum of embedding
    distances), which is split into three around it (a stellar subdivision).
:func:`flip_diagonals`
    The shared edge ``a b`` of two triangles ``(a, b, c)`` and ``(b, a, d)`` becomes
    ``c d`` when the network rates ``c d`` closer (a smaller embedding distance) and,
    for a flat quad (both diagonals fold the pair by less than ``flat_degrees``), when
    ``a b`` is not locally Delaunay instead: the ``qem`` training meshes have the
    Delaunay diagonal in flat quads (generator 1.1.0, docs/DATA.md), where either
    diagonal is the same surface and the network's choice is a guess. With the
    conditioning points, a quad also flips when the other diagonal's two triangles
    pass closer to the points it holds by more than a fraction (``fit_gain``): a
    data-dependent triangulation. The network proposes the edges and the points decide
    between the two diagonals of a quad, which the vertices alone leave ambiguous
    (a fold up or down); fit flips come before score flips, and neither kind turns
    back an edge the other made.

Both keep the guarantee of :func:`spacemesh.decode.decode`. Splitting a triangle around
a vertex it does not use gives three triangles whose new edges each have one halfedge in
two of them, and the new vertex one fan. Flipping ``a b`` to ``c d`` replaces two
triangles by two over the same quad boundary with the same orientation; it is refused
when ``c d`` is already an edge (the one case where it would make a doubled edge) or
``a`` or ``b`` has only three neighbours. The flips terminate: a flat flip is a
Delaunay flip (finitely many in a near-planar quad), a score flip lowers the sum of the
edges' embedding distances, a fit flip lowers the points' fit error by a fraction,
and no kind undoes another: a quad is flat or not whichever diagonal it has, and an
edge a fit flip made is left by score flips and one a score flip made by fit flips;
``MAX_FLIP_PASSES`` bounds the work regardless.
"""

from __future__ import annotations

import numpy as np

from spacemesh.connectivity import Connectivity
from spacemesh.decode.quad_fit import QuadFit
from spacemesh.encode import connectivity_from_faces
from spacemesh.primitives import bounding_spheres, edge_keys
from spacemesh.spacetime import operand_distances
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Passes of simultaneous non-overlapping flips at most.
MAX_FLIP_PASSES = 16
#: A score flip may not fold its pair by more than this (degrees), or than the pair
#: was folded before: the network's preference never creates a sharp crease.
MAX_NEW_FOLD = 90.0
#: How far outside a triangle (in barycentric coordinates) a reinserted vertex may project.
INSIDE_MARGIN = 0.1
#: How far from a triangle's plane a reinserted vertex may lie, in its longest sides.
MAX_HEIGHT = 0.5
#: Delaunay and score gains below these are ties (no flip).
ANGLE_EPS = 1e-9
SCORE_EPS = 1e-9
#: Fit gains (summed squared distances, [-1, 1] frame) below this are ties.
FIT_EPS = 1e-12
#: A fit flip's gain must also stand out of the points' noise by this many standard
#: deviations. Points at noise ``s`` off the true surface, which the wrong diagonal
#: misses by ``e_i``, gain ``G = sum e_i^2`` with noise ``2 s sqrt(G)``: ``G > 4 z^2
#: s^2``, with ``s^2`` the median squared distance of the points to the decoded mesh
#: (:attr:`spacemesh.decode.quad_fit.QuadFit.noise`). On the held-out set with points
#: jittered by 0.01 (the mean edge is 0.36), z = 2 gives decoded edge F1 0.936 where
#: the relative test alone gives 0.926 and no fit 0.928; with exact points it changes
#: nothing.
FIT_SIGNIFICANCE = 2.0
#: Priority tiers of the flips: flat Delaunay flips, then fit flips, then score flips.
DELAUNAY_TIER = 1e6
FIT_TIER = 1e3


def _faces_of(connectivity: Connectivity) -> list[IntArray]:
    indices, offsets = connectivity.faces()
    return [indices[offsets[f] : offsets[f + 1]] for f in range(len(offsets) - 1)]


def over_triangles(point: FloatArray, corners: FloatArray) -> BoolArray:
    """Whether ``point`` lies over each triangle: its projection onto the triangle's
    plane is inside (barycentric coordinates above ``-INSIDE_MARGIN``) and it is no
    farther from the plane than :data:`MAX_HEIGHT` times the triangle's longest side.

    Parameters
    ----------
    point : (3,) float
    corners : (T, 3, 3) float

    Returns
    -------
    (T,) bool
    """
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    u, v, w = b - a, c - a, point - a  # (T, 3)
    normal = np.cross(u, v)
    area2 = np.einsum("tk,tk->t", normal, normal)  # |2 area|^2
    with np.errstate(invalid="ignore", divide="ignore"):
        beta = np.einsum("tk,tk->t", np.cross(w, v), normal) / area2
        gamma = np.einsum("tk,tk->t", np.cross(u, w), normal) / area2
        height = np.abs(np.einsum("tk,tk->t", w, normal)) / np.sqrt(area2)
    side = np.max(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2), axis=1)
    inside = (beta > -INSIDE_MARGIN) & (gamma > -INSIDE_MARGIN)
    inside &= 1.0 - beta - gamma > -INSIDE_MARGIN
    return inside & (height <= MAX_HEIGHT * side) & (area2 > 0)


#: A point lies over a triangle (:func:`over_triangles`) only within this many times the
#: triangle's bounding radius of its centroid: its projection within 1.4 radii (every
#: barycentric coordinate above -0.1) and its height within one (half the longest side,
#: at most two radii) make at most 1.72.
OVER_REACH = 2.0


def _within_reach(point: FloatArray, centre: FloatArray, radius: FloatArray) -> IntArray:
    """Rows of the triangles (``centre`` ``(T, 3)``, ``radius`` ``(T,)``) that ``point``
    may lie over (:data:`OVER_REACH`), in order."""
    offset = centre - point
    return np.flatnonzero(np.einsum("tk,tk->t", offset, offset)
                          <= (OVER_REACH * radius) ** 2)


def reinsert_vertices(
    connectivity: Connectivity, removed: IntArray, operands: tuple[FloatArray, FloatArray],
    positions: FloatArray | None = None,
) -> tuple[Connectivity, int]:
    """Put removed vertices back, each into the triangle the network rates closest.

    With positions, only triangles the vertex lies over (:func:`over_triangles`) are
    candidates, so the three new triangles do not fold over their neighbours; a vertex
    over none stays out.

    Parameters
    ----------
    connectivity : Connectivity
        A valid decode over ``N`` vertices; the ``removed`` ones have degree 0.
    removed : (R,) int
        Vertices to put back (degree 0 in ``connectivity``).
    operands : tuple of two (N, k') float arrays
        Distance operands (:func:`spacemesh.spacetime.distance_operands`).
    positions : (N, 3) float, optional

    Returns
    -------
    connectivity : Connectivity
    inserted : int
    """
    faces = _faces_of(connectivity)
    triangles = [f for f in faces if len(f) == 3]
    others = [f for f in faces if len(f) != 3]
    removed = np.asarray(removed, dtype=np.int64)
    if not len(triangles) or not len(removed):
        return connectivity, 0
    tri = np.stack(triangles)  # (T, 3)
    live = np.flatnonzero(connectivity.degree > 0)
    # the most confident first: closest to its three nearest live vertices
    near = operand_distances(operands, removed[:, None], live[None, :])  # (R, L)
    confidence = np.sort(near, axis=1)[:, : min(3, len(live))].sum(axis=1)
    inserted = 0
    spheres = None if positions is None else bounding_spheres(positions[tri])
    for v in removed[np.argsort(confidence, kind="stable")].tolist():
        if positions is None or spheres is None:
            rows = np.arange(len(tri))
            cost = operand_distances(operands, np.full_like(tri, v), tri).sum(axis=1)  # (T,)
        else:  # the triangles it lies over, among those whose sphere could hold it
            rows = _within_reach(positions[v], *spheres)
            rows = rows[over_triangles(positions[v], positions[tri[rows]])]
            cost = operand_distances(operands, np.full_like(tri[rows], v), tri[rows]).sum(axis=1)
            if not np.isfinite(cost).any():
                continue
        t = int(rows[np.argmin(cost)])
        a, b, c = tri[t].tolist()
        made = np.array([[a, b, v], [b, c, v], [c, a, v]])
        tri = np.concatenate([tri[:t], made, tri[t + 1 :]])
        if positions is not None and spheres is not None:
            centre, radius = bounding_spheres(positions[made])
            spheres = (np.concatenate([spheres[0][:t], centre, spheres[0][t + 1 :]]),
                       np.concatenate([spheres[1][:t], radius, spheres[1][t + 1 :]]))
        inserted += 1
    if inserted == 0:
        return connectivity, 0
    return connectivity_from_faces([*tri, *others], connectivity.n_vertices), inserted


def _angle(o: FloatArray, u: FloatArray, v: FloatArray) -> FloatArray:
    """Angles at ``o`` of the triangles ``(o, u, v)``, rows of ``(E, 3)`` arrays."""
    x, y = u - o, v - o
    cos = np.einsum("ek,ek->e", x, y) / (
        np.linalg.norm(x, axis=1) * np.linalg.norm(y, axis=1) + 1e-300)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _fold(p: FloatArray, a: IntArray, b: IntArray, c: IntArray, d: IntArray) -> FloatArray:
    """Degrees between the normals of ``(a, b, c)`` and ``(b, a, d)``."""
    n1 = np.cross(p[b] - p[a], p[c] - p[a])
    n2 = np.cross(p[a] - p[b], p[d] - p[b])
    cos = np.einsum("ek,ek->e", n1, n2) / (
        np.linalg.norm(n1, axis=1) * np.linalg.norm(n2, axis=1) + 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _flip_candidates(
    tri: IntArray, edges: set[int], degree: IntArray, n: int,
    operands: tuple[FloatArray, FloatArray], positions: FloatArray | None,
    flat_degrees: float | None, by_score: bool, fit: QuadFit | None, fit_gain: float,
    made: dict[int, str],
) -> tuple[np.ndarray, FloatArray]:
    """Flippable interior edges of the triangles, best first.

    Returns the rows ``(t1, t2, a, b, c, d)`` (triangle ``t1`` holds ``a -> b`` opposite
    ``c``, ``t2`` holds ``b -> a`` opposite ``d``) and their priorities (larger first:
    flat Delaunay flips, then fit flips, then score flips). With ``fit``, a fit flip
    needs a relative gain above ``fit_gain``. ``made`` names the flip kind (``"fit"``
    or ``"score"``) that made an edge: the other kind leaves it.
    """
    src = tri.reshape(-1)
    dst = np.roll(tri, -1, axis=1).reshape(-1)
    opp = np.roll(tri, -2, axis=1).reshape(-1)
    face = np.repeat(np.arange(len(tri)), 3)
    key = src * n + dst
    order = np.argsort(key)
    twin_key = dst * n + src
    pos = np.searchsorted(key[order], twin_key)
    pos = np.minimum(pos, len(order) - 1)
    twin = order[pos]
    has_twin = key[twin] == twin_key
    h = np.flatnonzero(has_twin & (src < dst))
    g = twin[h]
    a, b, c, d = src[h], dst[h], opp[h], opp[g]
    new_keys = edge_keys(np.stack([c, d], axis=1), n)
    ok = (c != d) & (degree[a] > 3) & (degree[b] > 3)
    ok &= ~np.fromiter((k in edges for k in new_keys.tolist()), bool, len(new_keys))
    priority = np.full(len(h), -np.inf)
    flat = np.zeros(len(h), dtype=bool)
    if positions is not None:
        fold_ab = _fold(positions, a, b, c, d)
        fold_cd = _fold(positions, c, d, b, a)
        if flat_degrees is not None:
            flat = np.maximum(fold_ab, fold_cd) < flat_degrees
            p = positions
            excess = _angle(p[c], p[a], p[b]) + _angle(p[d], p[a], p[b]) - np.pi
            delaunay = flat & (excess > ANGLE_EPS)
            priority[delaunay] = DELAUNAY_TIER + excess[delaunay]
        creased = (fold_cd > MAX_NEW_FOLD) & (fold_cd > fold_ab)
    else:
        creased = np.zeros(len(h), dtype=bool)
    kind = [made.get(k, "") for k in edge_keys(np.stack([a, b], axis=1), n).tolist()]
    made_by = np.asarray(kind, dtype=object)
    if fit is not None and (ok & ~flat & (made_by != "score")).any():
        q = np.flatnonzero(ok & ~flat & (made_by != "score"))  # a score flip's edge stays
        pairs = np.stack([face[h[q]], face[g[q]]], axis=1)
        before, after = fit.errors(pairs, np.stack([a[q], b[q], c[q], d[q]], axis=1))
        with np.errstate(invalid="ignore", divide="ignore"):
            relative = (before - after) / before  # nan without points
        floor = max(FIT_EPS, 4.0 * FIT_SIGNIFICANCE**2 * fit.noise)
        fitted = (before - after > floor) & (relative > fit_gain)
        priority[q[fitted]] = FIT_TIER + relative[fitted]
    if by_score:
        gain = operand_distances(operands, a, b) - operand_distances(operands, c, d)
        scored = ~flat & ~creased & (made_by != "fit") & (gain > SCORE_EPS)
        scored &= ~np.isfinite(priority)
        priority[scored] = gain[scored]
    keep = ok & np.isfinite(priority)
    rows = np.stack([face[h], face[g], a, b, c, d], axis=1)[keep]
    priority = priority[keep]
    best = np.argsort(-priority, kind="stable")
    return rows[best], priority[best]


def flip_diagonals(
    connectivity: Connectivity, operands: tuple[FloatArray, FloatArray],
    positions: FloatArray | None = None, *, flat_degrees: float | None = None,
    by_score: bool = True, points: FloatArray | None = None, fit_gain: float | None = None,
) -> tuple[Connectivity, int]:
    """Flip the shared edges of triangle pairs to the diagonal the network or, in flat
    quads, the Delaunay criterion prefers (see the module docstring).

    Parameters
    ----------
    connectivity : Connectivity
        A valid decode.
    operands : tuple of two (N, k') float arrays
        Distance operands (:func:`spacemesh.spacetime.distance_operands`).
    positions : (N, 3) float, optional
        Needed for the flat rule and the crease guard.
    flat_degrees : float, optional
        Quads folded by less than this are flat: Delaunay flips there, no score flips.
    by_score : bool
        Flip non-flat quads to the diagonal with the smaller embedding distance.
    points : (P, 3) float, optional
        The conditioning point cloud, in the frame of ``positions`` (non-finite rows
        are left out).
    fit_gain : float, optional
        With ``points``: flip a non-flat quad when its points' summed squared distance
        to the other diagonal's two triangles is lower by more than this fraction and
        by more than the points' noise allows (:data:`FIT_SIGNIFICANCE`; a fit flip,
        before any score flip; :class:`spacemesh.decode.quad_fit.QuadFit`). A score flip
        never turns back an edge a fit flip made, nor a fit flip one a score flip
        made: the first to decide a quad keeps it.

    Returns
    -------
    connectivity : Connectivity
    flips : int
    """
    n = connectivity.n_vertices
    faces = _faces_of(connectivity)
    others = [f for f in faces if len(f) != 3]
    triangles = [f for f in faces if len(f) == 3]
    if len(triangles) < 2:
        return connectivity, 0
    tri = np.stack(triangles).astype(np.int64)  # (T, 3)
    fit = None
    if (fit_gain is not None and points is not None and len(points) and positions is not None
            and np.isfinite(positions[tri]).all()):
        fit = QuadFit(points, positions, tri)
        fit = fit if len(fit.points) else None
    if not by_score and fit is None and (flat_degrees is None or positions is None):
        return connectivity, 0
    edges = set(edge_keys(connectivity.edges, n).tolist())
    degree = connectivity.degree.astype(np.int64).copy()
    flips = 0
    made: dict[int, str] = {}  # edge key -> the kind of flip that made it
    for _ in range(MAX_FLIP_PASSES):
        rows, priority = _flip_candidates(tri, edges, degree, n, operands, positions,
                                          flat_degrees, by_score, fit, fit_gain or 0.0, made)
        used: BoolArray = np.zeros(len(tri), dtype=bool)
        done = 0
        changed = []
        for (t1, t2, a, b, c, d), tier in zip(rows.tolist(), priority.tolist(), strict=True):
            new = c * n + d if c < d else d * n + c
            if used[t1] or used[t2] or new in edges or degree[a] <= 3 or degree[b] <= 3:
                continue
            if tier < DELAUNAY_TIER:
                made[new] = "fit" if tier >= FIT_TIER else "score"
            tri[t1] = (d, b, c)
            tri[t2] = (c, a, d)
            used[t1] = used[t2] = True
            edges.discard(a * n + b if a < b else b * n + a)
            edges.add(new)
            degree[[a, b]] -= 1
            degree[[c, d]] += 1
            changed.append((t1, t2))
            done += 1
        if fit is not None:
            fit.flipped(np.asarray(changed, dtype=np.int64).reshape(-1, 2))
        flips += done
        if done == 0:
            break
    if flips == 0:
        return connectivity, 0
    return connectivity_from_faces([*tri, *others], n), flips
