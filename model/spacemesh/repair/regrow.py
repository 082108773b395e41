"""A marked region whose new faces still cross once its samplings and the mending of
:mod:`spacemesh.repair.crossings` are spent is grown around the crossings and
re-generated (:func:`regrow_crossings`), and an automatic repair's fills that still
cross are made again as a marked region of its output (:func:`refill_crossings`;
docs/REPAIR.md, "Limits").

What the samplings and the mending cannot fix comes from the kept faces the new ones
must meet: a loop that wraps around a strip of kept triangles with all their corners on
it (a flat region whose fill folds back onto them), or two loops whose fills cross each
other and a kept triangle between them. The region then takes in the kept faces its new
faces cross (where they cross only each other: every face with a corner on them), so
those are re-generated with it, and the repair runs again on the grown region (its own
samplings and mending), up to :data:`REGROW_ROUNDS` times. A grown repair is kept only
when it adds fewer handles, or as many and fewer crossing faces; a growth the plan
refuses (beyond ``max_growth``, too large for the model) ends the rounds with the repair
as it was. Taking in the whole ring around the crossing faces instead mended as many
dev repairs but fitted the input worse (docs/REPAIR.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from spacemesh.geometry.intersections import crossing_faces, crossing_pairs
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_touching, triangles_of, vertices_of
from spacemesh.primitives.graph import component_labels
from spacemesh.repair.region import RegionError
from spacemesh.repair.result import RepairResult, add_timings, new_face_degrees
from spacemesh.topology import face_adjacency
from spacemesh.typed import BoolArray, IntArray

#: Times a region still crossing is grown and re-generated.
REGROW_ROUNDS = 2


def crossing_new_faces(result: RepairResult) -> IntArray:
    """(P, 2) the pairs of faces of ``result.mesh`` that cross, at least one of them new."""
    mesh, new = result.mesh, result.face_source < 0
    triangles, face = triangles_of(mesh)  # (T, 3), (T,)
    among = np.flatnonzero(new[face])
    pairs = face[crossing_pairs(mesh.vertices, triangles, face, among)]  # (P, 2)
    return pairs[new[pairs].any(axis=1)]


def grown_around(mesh: PolygonMesh, result: RepairResult, pairs: IntArray) -> BoolArray:
    """(F,) ``result.region`` and the faces of ``mesh`` (the input) that a new face of
    ``result`` crosses (``pairs``: its crossing pairs); where new faces cross only each
    other, every face of ``mesh`` with a corner on one of them instead."""
    crossed = result.face_source[pairs.reshape(-1)]  # (2P,) input face, -1: new
    grown = result.region.copy()
    grown[crossed[crossed >= 0]] = True
    if not np.array_equal(grown, result.region):
        return grown
    crossing = np.zeros(result.mesh.n_faces, dtype=bool)
    crossing[pairs.reshape(-1)] = True
    touched = vertices_of(result.mesh, crossing)  # (V_out,)
    vertex_map = result.vertex_map  # (V_in,) output vertex, -1: removed
    touched_input = (vertex_map >= 0) & touched[np.maximum(vertex_map, 0)]  # (V_in,)
    return result.region | faces_touching(mesh, touched_input)


def regrow_crossings(mesh: PolygonMesh, result: RepairResult,
                     repair: Callable[[BoolArray], RepairResult],
                     rounds: int = REGROW_ROUNDS) -> RepairResult:
    """``result``, or the repair of a region grown around its crossings when that one
    crosses less (the module's rule).

    Parameters
    ----------
    mesh : PolygonMesh
        The input mesh ``result`` repaired.
    result : RepairResult
        The repair of the marked region.
    repair : callable
        ``repair(region)``: the same repair of another region ((F,) bool in ``mesh``'s
        faces), without regrowing.
    rounds : int
        Most growths.

    Returns
    -------
    RepairResult
        Its stats keep the faces the user asked for (``requested_faces``), count the
        growth in ``grown_faces`` and, in ``fill``, ``regrown_faces`` (faces the
        crossings added to the region) and ``regrowths`` (re-generations run); the
        samplings and timings of every run are summed.
    """
    first, best = result, result
    pairs = crossing_new_faces(result)
    samplings, timings = result.stats.samplings, dict(result.stats.timings)
    runs = 0
    for _ in range(rounds):
        if len(pairs) == 0:
            break
        grown = grown_around(mesh, best, pairs)
        if np.array_equal(grown, best.region):
            break
        try:
            again = repair(grown)
        except RegionError:
            break  # grown beyond what the plan allows: the repair as it was
        runs += 1
        samplings += again.stats.samplings
        add_timings(timings, again.stats.timings)
        again_pairs = crossing_new_faces(again)
        if (again.stats.handles_added, _crossing_count(again_pairs)) < (
                best.stats.handles_added, _crossing_count(pairs)):
            best, pairs = again, again_pairs
        else:
            break
    if runs == 0:
        return result
    stats = best.stats
    requested = first.stats.requested_faces
    fill = dict(stats.fill)
    fill["regrown_faces"] = int(best.region.sum() - first.region.sum())
    fill["regrowths"] = runs
    return replace(best, stats=replace(
        stats, requested_faces=requested, grown_faces=stats.region_faces - requested,
        fill=fill, samplings=samplings, timings=timings))


def _crossing_count(pairs: IntArray) -> int:
    """Faces in the crossing ``pairs``."""
    return len(np.unique(pairs))


def refill_crossings(result: RepairResult,
                     repair: Callable[[BoolArray], RepairResult]) -> RepairResult:
    """An automatic repair's fills that cross, re-generated as a marked region of its
    output (the samplings, the mending and the growth of :func:`regrow_crossings`): the
    crossing faces alone, else, where crossings remain, the fills they belong to whole;
    the one with the fewest crossing faces is kept when fewer cross than before.

    Parameters
    ----------
    result : RepairResult
        An automatic repair (its ``region`` in the faces of the plan's working mesh).
    repair : callable
        ``repair(region)``: the marked-region repair of ``region`` ((F_out,) bool) of
        ``result.mesh``, regrowing included.

    Returns
    -------
    RepairResult
        ``result``, or the two repairs composed: the faces and vertices of the second,
        their sources and the vertex map traced back to the input, the region the input
        faces either removed. The stats count the faces again (``new_vertices``,
        ``new_faces``, ``new_face_degrees``, ``region_faces``) and give, in ``fill``,
        ``refilled_faces`` (the fills' faces re-generated), ``regrown_faces`` (input
        faces the second repair took in, outside the planned regions) and ``refills``
        (the re-generations run); the samplings and timings of every run are summed, also
        when none is kept (``refills`` alone then).
    """
    mesh, new = result.mesh, result.face_source < 0
    crossing = crossing_faces(mesh, new)  # (K,) new faces crossing a face
    if len(crossing) == 0:
        return result
    alone = np.zeros(mesh.n_faces, dtype=bool)
    alone[crossing] = True
    adjacent = face_adjacency(mesh)  # (A, 2)
    _, label = component_labels(mesh.n_faces, adjacent[new[adjacent].all(axis=1)])
    whole = new & np.isin(label, label[crossing])  # (F_out,) the crossing fills, whole
    best: tuple[int, BoolArray, RepairResult, IntArray] | None = None
    tries, samplings = 0, result.stats.samplings
    timings = dict(result.stats.timings)
    for refill in (alone, whole):
        if tries and np.array_equal(refill, alone):
            continue  # the fills are the crossing faces: tried already
        try:
            again = repair(refill)
        except RegionError:
            continue  # cannot be planned as a region (too large, a hole left open)
        tries, samplings = tries + 1, samplings + again.stats.samplings
        add_timings(timings, again.stats.timings)
        source = np.where(again.face_source >= 0,  # (F_again,) input face, -1: new
                          result.face_source[np.maximum(again.face_source, 0)], -1)
        count = len(crossing_faces(again.mesh, source < 0))
        if count < (len(crossing) if best is None else best[0]):
            best = (count, refill, again, source)
        if count == 0:
            break
    if best is None:  # none ran, or none crossed less: the time they took is counted
        fill = {**result.stats.fill, "refills": tries} if tries else result.stats.fill
        return result if not tries else replace(result, stats=replace(
            result.stats, fill=fill, samplings=samplings, timings=timings))
    _, refill, again, face_source = best
    taken = result.face_source[again.region & ~new]  # input faces the second removed
    region = result.region.copy()
    region[taken] = True
    vertex_map = np.where(result.vertex_map >= 0,
                          again.vertex_map[np.maximum(result.vertex_map, 0)], -1)
    out = again.mesh
    added = face_source < 0
    kept_vertices = np.unique(vertex_map[vertex_map >= 0])
    fill = {**result.stats.fill, "refills": tries, "refilled_faces": int(refill.sum()),
            "regrown_faces": len(taken)}
    stats = replace(
        result.stats, region_faces=int(region.sum()),
        new_vertices=out.n_vertices - len(kept_vertices), new_faces=int(added.sum()),
        new_face_degrees=new_face_degrees(out, added),
        fill=fill, samplings=samplings, timings=timings)
    return replace(result, mesh=out, vertex_map=vertex_map, face_source=face_source,
                   region=region, stats=stats)
