"""A marked region whose new faces still cross once its samplings and the mending of
:mod:`spacemesh.repair.crossings` are spent is grown around the crossings and
re-generated (docs/REPAIR.md, "Limits").

What the samplings and the mending cannot fix comes from the kept faces the new ones
must meet: a loop that wraps around a strip of kept triangles with all their corners on
it (a flat region whose fill folds back onto them), or two loops whose fills cross each
other and a kept triangle between them. The region then takes in every face with a
corner on a crossing face (new or kept), so those kept triangles are re-generated with
it, and the repair runs again on the grown region (its own samplings and mending), up to
:data:`REGROW_ROUNDS` times. A grown repair is kept only when it adds fewer handles, or
as many and fewer crossing faces; a growth the plan refuses (beyond ``max_growth``, too
large for the model) ends the rounds with the repair as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from spacemesh.geometry.intersections import crossing_pairs
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_touching, triangles_of, vertices_of
from spacemesh.repair.region import RegionError
from spacemesh.repair.result import RepairResult
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
        for key, value in again.stats.timings.items():
            timings[key] = timings.get(key, 0.0) + value
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
