"""From a valid decode to the mesh a user gets: fragments out, the geometry stage, outward
orientation, and the choice between the upload's normals and none.

An upload's normals enter only the geometry stage's tangent-plane quadrics
(:func:`spacemesh.geometry.refine_geometry`). True normals of a faceted or creased
surface pin vertices that farthest-point sampling put *near* a crease onto it, which on
some shapes (a cube, a faceted cylinder, low-poly organics) fits worse than the plane
fits' own normals. So with normals the stage runs twice, with them and without, and the
mesh whose fit scores better (:func:`spacemesh.geometry.report.fit_score`, the fit
report's score against the same points) is kept: normals never make the result fit the
points worse. On the 27 dev meshes this gave CD 1.17e-3 against 1.22e-3 from bare points and
1.30e-3 with the normals always used, and no mesh more than 10% worse than without.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from spacemesh.geometry.pieces import drop_fragments
from spacemesh.geometry.report import fit_score, points_to_mesh_mean
from spacemesh.geometry.simplify import simplify
from spacemesh.geometry.stage import GeometryOptions, GeometryResult, refine_geometry
from spacemesh.geometry.surface import face_support, open_surface
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import flip_faces, signed_volume
from spacemesh.topology import check_topology
from spacemesh.typed import FloatArray

#: ``max_distance``: the collapses may first leave the mesh this many times that distance
#: from the points (its fit brings it closer; tuned on the dev split) ...
SIMPLIFY_SHARE = 1.5
#: ... and while the fitted mesh misses it, they run again from the dense mesh with the
#: allowance shrunk by the miss (at least by this factor), at most this many times in all.
SHRINK = 0.8
SIMPLIFY_TRIES = 3
#: A dense decode is fitted without flips (``GeometryOptions.dense_flips`` false) only when
#: it has at least this many times the vertices asked for: near the count (1,024 decoded
#: for 1,000) the collapses change little, and without flips ``target_vertices=1000``
#: ran 4 times longer on the bench (more seeds and fallbacks ran).
DENSE_NO_FLIPS = 1.5


def outward(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` with its faces flipped when its signed volume is negative."""
    return flip_faces(mesh) if mesh.n_faces and signed_volume(mesh) < 0 else mesh


def finish_geometry(
    mesh: PolygonMesh,
    points: FloatArray,
    normals: FloatArray | None,
    options: GeometryOptions,
    *,
    target_vertices: int | None = None,
    max_distance: float | None = None,
) -> tuple[PolygonMesh, dict[str, Any]]:
    """Drop fragments, then run the geometry stage (see the module docstring).

    An open mesh (one with a rim: a decode trimmed to its points) is fitted without
    flips and keeps its orientation, which its points gave it (an open surface has no
    signed volume to orient it by).

    Parameters
    ----------
    mesh : PolygonMesh
        A valid decode in the normalised frame.
    points : (P, 3) float
        The normalised points the stage fits to.
    normals : (P, 3) float, optional
        The upload's normals: the stage runs with them and without, and the better fit
        is kept.
    options : GeometryOptions
    target_vertices : int, optional
        The vertices asked for: with a dense decode (``options.dense_factor`` above 1) a
        mesh with more is simplified to this many first
        (:func:`spacemesh.geometry.simplify.simplify`); one with fewer gets its edges
        split up to it.
    max_distance : float, optional
        Simplify to a distance instead (``tolerance``): the decode, fitted, is collapsed
        for as long as the mean distance from the points to it stays within this
        (:func:`spacemesh.geometry.simplify.simplify`'s ``max_distance``), whatever
        ``target_vertices`` and the dense decode, then fitted at its own count.

    Returns
    -------
    mesh : PolygonMesh
        Outward oriented (an open mesh: as it came), in the normalised frame.
    stats : dict
        The stage's statistics, ``n_fragments_dropped`` and, with normals,
        ``normals_used`` (whether the kept mesh was fitted with them).
    """
    closed = check_topology(mesh).is_closed
    if not closed:
        options = replace(options, flips=False)  # the flips need a closed mesh
    mesh, dropped = drop_fragments(mesh)
    simplified: dict[str, Any] = {}
    fitted_already: GeometryResult | None = None  # the fit with ``normals``, when made
    if max_distance is not None:
        # simplified to a distance: the count follows the shape
        dense = refine_geometry(mesh, points, normals, options).mesh
        mesh, simplified, fitted_already = _simplified_within(
            dense, points, normals, options, max_distance)
        target_vertices = None
    elif (options.dense_factor > 1 and target_vertices is not None
            and mesh.n_vertices > target_vertices):
        # a dense decode: fitted to the points first (the collapses' placements and
        # costs read the fitted surface; flips only with ``dense_flips`` or near the
        # count, DENSE_NO_FLIPS), then collapsed to the count asked for, the points'
        # planes the cost
        flips = options.flips and (options.dense_flips
                                   or mesh.n_vertices < DENSE_NO_FLIPS * target_vertices)
        dense = refine_geometry(mesh, points, normals, replace(options, flips=flips)).mesh
        reduced = simplify(dense, points, normals, target_vertices=target_vertices)
        mesh, simplified = reduced.mesh, {"simplify": reduced.stats}
    tries = [normals] if normals is None else [normals, None]
    best: tuple[float, PolygonMesh, dict[str, Any]] | None = None
    for given in tries:
        refined = (fitted_already if fitted_already is not None and given is normals
                   else refine_geometry(mesh, points, given, options,
                                        target_vertices=target_vertices))
        fitted = outward(refined.mesh) if closed else refined.mesh
        stats = dict(refined.stats, n_fragments_dropped=dropped, **simplified)
        if normals is not None:
            stats["normals_used"] = given is not None
        score = fit_score(fitted, points) if len(tries) > 1 else 0.0
        score = score if np.isfinite(score) else np.inf
        if best is None or score < best[0]:
            best = (score, fitted, stats)
    assert best is not None  # at least one try
    return best[1], best[2]


def fit_trimmed_first(
    decoded: PolygonMesh,
    points: FloatArray,
    normals: FloatArray | None,
    options: GeometryOptions,
    *,
    target_vertices: int | None = None,
    max_distance: float | None = None,
) -> tuple[PolygonMesh, dict[str, Any]] | None:
    """An open surface's second candidate: its closed decode trimmed to the points
    (:func:`spacemesh.geometry.surface.open_surface`) *before* the geometry stage, then
    fitted (:func:`finish_geometry`, which keeps an open mesh's orientation).

    The geometry stage fits a closed mesh as a whole: its unseen side is pulled onto the
    points and drags the seen side with it, so the mesh trimmed afterwards can leave
    points uncovered. Trimmed first, the stage fits only where the points are, and every
    vertex asked for lies there (docs/GEOMETRY.md, "Open surfaces").

    Parameters
    ----------
    decoded : PolygonMesh
        A valid closed decode in the normalised frame, outward.
    points, normals, options, target_vertices, max_distance
        As :func:`finish_geometry`'s.

    Returns
    -------
    (PolygonMesh, dict) or None
        The fitted open mesh and the stage's statistics with the trimming's; None when
        the points support none or all of the decode's faces (nothing to trim).
    """
    trimmed, trimming = open_surface(decoded, face_support(decoded, points, normals))
    if trimmed is decoded:
        return None
    mesh, stats = finish_geometry(trimmed, points, normals, options,
                                  target_vertices=target_vertices, max_distance=max_distance)
    return mesh, {**stats, **trimming}


def _simplified_within(dense: PolygonMesh, points: FloatArray, normals: FloatArray | None,
                       options: GeometryOptions, max_distance: float
                       ) -> tuple[PolygonMesh, dict[str, Any], GeometryResult]:
    """``dense`` (fitted) collapsed for as long as the mean distance from ``points``
    stays within :data:`SIMPLIFY_SHARE` times ``max_distance``, then fitted; while the
    fitted mesh's mean distance (:func:`spacemesh.geometry.report.points_to_mesh_mean`)
    misses ``max_distance``, collapsed again from ``dense`` with the allowance shrunk by
    the miss, at most :data:`SIMPLIFY_TRIES` times in all.

    Returns
    -------
    mesh : PolygonMesh
        The collapsed mesh, before its fit.
    stats : dict
        ``{"simplify": ...}``: the last collapse's statistics, ``tries`` and the fitted
        mesh's ``fitted_distance``.
    fitted : GeometryResult
        Its fit (with ``normals``).
    """
    allowed = SIMPLIFY_SHARE * max_distance
    tries = 0
    while True:
        tries += 1
        reduced = simplify(dense, points, normals, max_distance=allowed)
        fitted = refine_geometry(reduced.mesh, points, normals, options)
        distance = points_to_mesh_mean(fitted.mesh, points)
        if distance <= max_distance or reduced.mesh is dense or tries == SIMPLIFY_TRIES:
            break
        allowed *= min(max_distance / distance, SHRINK)
    stats = {**reduced.stats, "tries": tries, "fitted_distance": distance}
    return reduced.mesh, {"simplify": stats}, fitted
