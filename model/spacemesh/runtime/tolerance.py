"""``tolerance``: the smallest mesh whose points fit within a distance.

A request with ``tolerance = t`` asks for the smallest mesh whose mean distance from the
input points to the mesh (the fit report's ``points_to_mesh_mean_rel``, a fraction of
the input's bounding-box diagonal) is at most ``t``. The points are a sample of the
surface and the geometry stage fits the mesh to exactly them, so the distance from the
rest of the surface is larger than theirs: it aims at ``TOLERANCE_MARGIN * t``
(:func:`aim`).

First, one generate: its decode (the model's dense one), fitted, is collapsed for as long
as the mean distance from the points stays within the aim (:func:`simplify_distance`,
:func:`spacemesh.geometry.finishing.finish_geometry`'s ``max_distance``), then fitted;
it is taken when its points are within the aim. Only where it misses (a tolerance tighter
than the dense decode reaches, or a fit that moved away) does a search run, the first
generate counted among its :data:`MAX_TRIES`. The distance falls as vertices are added,
though not strictly, so :func:`search_vertex_count` brackets the count on a doubling
ladder from the model's default count and bisects the bracket geometrically:

1. generate at the default count (200 for the shipped model);
2. within the aim: halve the count until it is not (or :data:`MIN_SEARCH_VERTICES`);
   not: double it until it is (or :data:`MAX_SEARCH_VERTICES`, and never more vertices
   than the points: :func:`most_vertices`);
3. bisect between the largest count that missed and the smallest that met until they
   are within :data:`BRACKET_RATIO` of each other, or :data:`MAX_TRIES` meshes were made.

The smallest mesh within the aim is returned; when none was (the cap or the tries ran
out), the one closest to it. Its fit report's ``tolerance_met`` says whether its points
are within ``t`` itself.
Each search try is a whole generate at ``target_vertices = count`` with the request's
other options, so its result is the same mesh a request for that count would get.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TypeVar

import numpy as np

from spacemesh.runtime.options import GenerateOptions
from spacemesh.typed import FloatArray

#: Fewest and most vertices the search tries.
MIN_SEARCH_VERTICES = 8
MAX_SEARCH_VERTICES = 4_000
#: The search aims at this share of the tolerance: the input points are a sample of the
#: surface, and the fit pulls the mesh onto them, so the distance from the rest of the
#: surface is larger than theirs. Not tuned yet: at 1.0 the truth was within 0.005 on
#: 71% of the test meshes.
TOLERANCE_MARGIN = 0.8
#: Most meshes one search makes (its time is about this many generates).
MAX_TRIES = 8
#: The bisection stops once the smallest count that met and the largest that missed are
#: within this ratio.
BRACKET_RATIO = 1.15

#: A generate's result (:class:`~spacemesh.runtime.request.GenerateResult`).
Result = TypeVar("Result")


def distance_of(result: object) -> float:
    """The fit report's ``points_to_mesh_mean_rel`` of a result (inf without one)."""
    fit = getattr(result, "fit", None)
    value = float("inf") if fit is None else float(fit.points_to_mesh_mean_rel)
    return value if np.isfinite(value) else float("inf")


def search_vertex_count(
    run: Callable[[int], Result],
    tolerance: float,
    start: int,
    *,
    on_try: Callable[[int, int], None] | None = None,
    max_tries: int = MAX_TRIES,
    most: int = MAX_SEARCH_VERTICES,
) -> tuple[Result, bool, list[tuple[int, float]]]:
    """Find the smallest vertex count whose mesh fits within ``tolerance``.

    Parameters
    ----------
    run : callable
        ``run(count)``: the result generated at ``target_vertices = count``.
    tolerance : float
        Most ``points_to_mesh_mean_rel`` allowed.
    start : int
        The first count tried (clipped to the search's range).
    on_try : callable, optional
        ``on_try(k, max_tries)`` before the ``k``-th try (1-based).
    max_tries : int
        Most tries (:data:`MAX_TRIES`).
    most : int
        Most vertices tried (:data:`MAX_SEARCH_VERTICES`, or fewer: :func:`most_vertices`).

    Returns
    -------
    result
        The smallest result that met the tolerance, else the closest one.
    met : bool
    tried : list of (int, float)
        Every count tried and its distance, in order.
    """
    most = int(min(max(most, MIN_SEARCH_VERTICES), MAX_SEARCH_VERTICES))
    count = int(min(max(start, MIN_SEARCH_VERTICES), most))
    results: dict[int, Result] = {}
    tried: list[tuple[int, float]] = []
    smallest_met: int | None = None
    largest_missed: int | None = None
    for k in range(1, max_tries + 1):
        if on_try is not None:
            on_try(k, max_tries)
        result = run(count)
        results[count] = result
        distance = distance_of(result)
        tried.append((count, distance))
        if distance <= tolerance:
            smallest_met = count if smallest_met is None else min(smallest_met, count)
        else:
            largest_missed = count if largest_missed is None else max(largest_missed, count)
        following = _next_count(smallest_met, largest_missed, most)
        if following is None or following in results:
            break
        count = following
    if smallest_met is not None:
        return results[smallest_met], True, tried
    closest = min(tried, key=lambda pair: (pair[1], pair[0]))[0]
    return results[closest], False, tried


def _next_count(smallest_met: int | None, largest_missed: int | None,
                most: int = MAX_SEARCH_VERTICES) -> int | None:
    """The next count to try (at most ``most``), or None when the search is done."""
    if smallest_met is None:  # nothing met yet: double, up to the cap
        assert largest_missed is not None
        if largest_missed >= most:
            return None
        return min(2 * largest_missed, most)
    if largest_missed is None:  # everything met so far: halve, down to the floor
        if smallest_met <= MIN_SEARCH_VERTICES:
            return None
        return max(smallest_met // 2, MIN_SEARCH_VERTICES)
    if smallest_met <= largest_missed or smallest_met <= BRACKET_RATIO * largest_missed:
        return None  # bracketed (or the distance went up with the count: stop there)
    middle = round(math.sqrt(smallest_met * largest_missed))
    return middle if largest_missed < middle < smallest_met else None


def most_vertices(points: int) -> int:
    """The most vertices a search tries for ``points`` input points: no more than the
    points (a mesh with more vertices than points is not determined by them; on 2,048
    points the search otherwise climbed to 3,200 vertices on thin parts, minutes of
    work for a mesh no closer to the truth), within :data:`MAX_SEARCH_VERTICES`."""
    return int(min(max(points, MIN_SEARCH_VERTICES), MAX_SEARCH_VERTICES))


def simplify_distance(tolerance: float, points: FloatArray) -> float:
    """The mean distance a mesh simplified to ``tolerance`` may keep from ``points``
    (:func:`spacemesh.geometry.finishing.finish_geometry`'s ``max_distance``): the
    :func:`aim`, in the units of ``points``.

    Parameters
    ----------
    tolerance : float
        The request's tolerance, a fraction of the points' bounding-box diagonal.
    points : (P, 3) float
        The points the mesh is fitted to (the normalised frame).

    Returns
    -------
    float
    """
    diagonal = float(np.linalg.norm(np.ptp(np.asarray(points, np.float64), axis=0)))
    return aim(tolerance) * diagonal


def aim(tolerance: float) -> float:
    """The distance the search aims at for a requested ``tolerance``."""
    return TOLERANCE_MARGIN * tolerance


def attempt_options(options: GenerateOptions, count: int) -> GenerateOptions:
    """One try's options: the request's, with ``target_vertices = count`` instead of the
    tolerance. Resolved options stay resolved (the search's counts,
    :data:`MIN_SEARCH_VERTICES` to :data:`MAX_SEARCH_VERTICES`, are valid targets), so a
    try needs no second resolution."""
    assert MIN_SEARCH_VERTICES <= count <= MAX_SEARCH_VERTICES, count
    return replace(options, tolerance=None, target_vertices=int(count))
