"""What a request will cost, estimated before any work starts: seconds and peak memory.

:class:`CostModel` turns what is known about a request once its input is read (the points
after the service's reduction, the resolved options, the model's retry seeds; for a
repair its steps, passes and mesh size) into an :class:`Estimate`: estimated seconds and
peak memory (MB), and, per input the request can lower, what lowering it would save.
:mod:`spacemesh.runtime.budget` refuses an estimate over a budget.

The formula, in seconds on the reference machine (2 CPU cores, one onnxruntime thread per
core; ``bench/bench_cost_model.py`` times the real pipeline against it)::

    seconds  = 1.05e-5 P + once + seeds * per_seed(N, V) + fewer
               (tolerance: a sum over its tries)
    per_seed = 7.3e-7 P + 5.6e-5 N                       farthest-point start
             + D (7.8e-6 N + 3.67e-8 N^2)                the denoiser steps that run
             + 1.3e-4 N                                  connectivity network
             + f (3.2e-7 N^2 + 0.25 + 1.61e-3 V + 1.86e-7 V^2)   decode, geometry stage
             + f (1.61e-3 W + 1.86e-7 W^2 + 1.5e-3 (W - V))      with a dense decode
             + 5.6e-6 min(P, 20000) + 4e-5 V             fit report
    once     = 5e-6 V^2                                  face_type=polygons: the flat collapses
    seeds    = max over k <= samples of k + R(k) 0.5 ** k,   R(k) = max(0, 1 + retry_seeds - k)
    fewer    = 0.25 ((samples + 0.5 R(samples)) per_seed(at F) + 0.25 + 1.61e-3 V + 1.86e-7 V^2)
    MB       = 3.5e-3 min(P, 20000) + 5.2e-4 P + 1.7e-4 (1 + 1.5 s) N^2 + 0.02 V + 0.006 N seeds

``P``: input points (after the reduction), ``V``: vertices asked for (``target_vertices``,
else the model's count), ``N``: vertex tokens the networks place (``V``, at most 2,048
outside ``raw``, :mod:`spacemesh.runtime.large`), ``W``: the dense decode's vertices
(:attr:`spacemesh.geometry.GeometryOptions.dense_factor`; fitted, then collapsed to
``V``; the term is absent without one), ``D``: denoiser steps that run (with
``start=points`` only those below ``start_time``), ``s``: the start time (1 from noise),
``f = 1 + 1.3 s``: denoised vertices lie less evenly than farthest points, and the decode
and the geometry stage take about twice as long on them. The model's retry seeds run only
when none of the request's seeds passes the topology check, and only to top the request
up to ``1 + retry_seeds`` seeds (``R``); the estimate counts them at
an even chance per seed (``0.5 ** samples``), and never estimates more samples cheaper
than fewer. A mesh that still crosses after the untangling is made again from ``F``
vertices (:func:`spacemesh.runtime.network.fewer_vertices`: the model's count, or half
the count asked for) and split back up to ``V``; the estimate counts it at a chance of
0.25 (absent with ``raw``, from noise, or where no count is left). An open surface's
second candidate (one more geometry stage for the chosen seed, made only once the
points read as a one-sided scan: :meth:`spacemesh.runtime.MeshGenerator._trimmed_first`)
is not counted; it is at most one ``per_seed``'s decode and geometry terms. Nor is the
third candidate of an open surface whose points form a flat sheet (the whole request
again on the points and their copy behind them, closed:
:meth:`spacemesh.runtime.MeshGenerator._flat_slab`): it doubles such a request. A ``tolerance``
request counts as 8 tries (its simplified generate and the search that may follow it;
:meth:`CostModel.tolerance_tries`): the doubling ladder from
the model's count to the count whose mesh is expected within the tolerance (a mean
distance of ``0.5 / V`` of the diagonal: twice the example torus's), the other tries at
that count, each costing the request's seeds. A repair::

    seconds = 1.75 passes (0.0165 D N / 256 + 0.35) + 2e-6 F
            + fills (0.58 + 2.2e-6 F) + 1.5e-4 sum(h^2) + 5.6e-6 F auto
    MB      = 30 + 9e-4 F

``D``: its sampler steps, ``N``: the model's tokens, ``F``: the mesh's faces, 1.75 the
expected samplings of up to three (a fill that adds a handle is sampled again),
``passes``: its model passes (1 for a marked region; for an automatic one a pass per
region re-generated whole and per wedge of the fan over each hole filled in place),
``fills``: the regions of holes whose fill is then refined, faired and probed (each
reads the mesh around its hole, and some of the whole mesh), ``h``: the vertices of each
of their holes (a hole's fill grows with its area), ``auto``: 1 for an automatic region
(orienting the mesh and finding its holes and defects read the whole mesh). Fitted on
icospheres of 20,000 to 327,000 faces with 1 to 20 holes of 16 to 269 vertices (within
12% of every measured time; ``bench/bench_cost_model.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from spacemesh.runtime.large import network_vertices
from spacemesh.runtime.network import (
    decode_count,
    denoiser_steps,
    fewer_vertices,
    sampler_key,
    vertex_count,
)
from spacemesh.runtime.options import MAX_TOLERANCE, MIN_TARGET_VERTICES, GenerateOptions
from spacemesh.runtime.spec import ModelSpec
from spacemesh.runtime.tolerance import (
    MAX_SEARCH_VERTICES,
    MAX_TRIES,
    MIN_SEARCH_VERTICES,
    aim,
)

#: Points the fit report measures at most (a fixed subset of larger clouds).
REPORT_POINTS = 20_000
#: Samplings of a repair at most (a fill that adds a handle is sampled again).
REPAIR_SAMPLINGS = 3

#: ``estimate(values) -> (seconds, MB)`` of one request with some of its inputs changed.
Formula = Callable[[Mapping[str, float | None]], tuple[float, float]]


@dataclass(frozen=True)
class Lever:
    """An input of a request that costs less when lowered (``tolerance``: raised).

    Attributes
    ----------
    name : str
        The option's public name (``samples``, ``target_vertices`` ...), ``points``, or for
        a repair ``region`` (its passes) and ``mesh`` (its faces).
    value : float
        The request's value.
    reference : float or None
        What its saving is measured against: the model's default (None: the option left
        out, e.g. no ``tolerance``).
    cheapest : float
        The cheap end of the values a suggestion is searched in.
    integer : bool
    raise_to_save : bool
        The request costs less as the value grows (``tolerance``).
    """

    name: str
    value: float
    reference: float | None
    cheapest: float
    integer: bool = True
    raise_to_save: bool = False

    @property
    def costly(self) -> bool:
        """Whether the request's value is beyond the cheap end."""
        return self.value < self.cheapest if self.raise_to_save else self.value > self.cheapest


@dataclass(frozen=True)
class Estimate:
    """A request's estimated cost, and what each of its levers would save.

    Attributes
    ----------
    seconds : float
    memory_mb : float
        Peak memory over the server's before the request (MB).
    levers : tuple of Lever
        The inputs the request set above their reference.
    formula : callable
        ``formula(changes) -> (seconds, MB)``: the same request with ``changes``
        (lever name -> value; None leaves an option out).
    """

    seconds: float
    memory_mb: float
    levers: tuple[Lever, ...]
    formula: Formula

    def with_changes(self, changes: Mapping[str, float | None]) -> tuple[float, float]:
        """``(seconds, MB)`` of the same request with ``changes``."""
        return self.formula(changes)

    def savings(self) -> dict[str, tuple[float, float]]:
        """Seconds and MB each lever saves at its reference, by name."""
        saved = {}
        for lever in self.levers:
            seconds, memory = self.with_changes({lever.name: lever.reference})
            saved[lever.name] = (max(0.0, self.seconds - seconds),
                                 max(0.0, self.memory_mb - memory))
        return saved

    def to_dict(self) -> dict[str, float]:
        """``{"seconds", "memory_mb"}``, rounded."""
        return {"seconds": round(self.seconds, 2), "memory_mb": round(self.memory_mb, 1)}


def _final_count(spec: ModelSpec, options: GenerateOptions) -> int:
    """The vertices a request's mesh is estimated at: the count asked for with
    ``start=points``, the model's tokens from noise (the network picks the count)."""
    return vertex_count(spec, options) if options.start == "points" else spec.max_vertices


@dataclass(frozen=True)
class CostModel:
    """The calibrated coefficients (the module docstring's formula) and the estimates.

    Seconds are on the reference machine (2 cores); memory is the peak RSS a request
    adds to a warmed-up server. Calibrated by ``bench/bench_cost_model.py`` on the
    example torus (``examples/points.ply``) and torus clouds of 20,000 to 200,000 points.
    """

    prepare_s_per_point: float = 1.05e-5
    fps_s_per_point: float = 7.3e-7
    fps_s_per_token: float = 5.6e-5
    step_s1: float = 7.8e-6
    step_s2: float = 3.67e-8
    connect_s: float = 1.3e-4
    decode_s2: float = 3.2e-7
    geometry_s0: float = 0.25
    geometry_s1: float = 1.61e-3
    geometry_s2: float = 1.86e-7
    collapse_s: float = 1.5e-3
    polygons_s2: float = 5e-6
    report_s_per_point: float = 5.6e-6
    report_s_per_vertex: float = 4e-5
    denoised_slowdown: float = 1.3
    retry_chance: float = 0.5
    fewer_chance: float = 0.25
    tolerance_scale: float = 0.5
    report_mb_per_point: float = 3.5e-3
    points_mb: float = 5.2e-4
    tokens_mb: float = 1.7e-4
    denoised_tokens_mb: float = 1.5
    vertex_mb: float = 0.02
    seed_mb_per_token: float = 0.006
    repair_step_s: float = 0.0165
    repair_pass_s: float = 0.35
    repair_s_per_face: float = 2e-6
    repair_fill_s: float = 0.58
    repair_fill_s_per_face: float = 2.2e-6
    repair_fill_s_per_vertex2: float = 1.5e-4
    repair_auto_s_per_face: float = 5.6e-6
    repair_mb: float = 30.0
    repair_mb_per_face: float = 9e-4

    # ------------------------------------------------------------------ generate
    def generate(self, spec: ModelSpec, options: GenerateOptions, points: int) -> Estimate:
        """The estimate of a generate request.

        Parameters
        ----------
        spec : ModelSpec
        options : GenerateOptions
            Resolved (:meth:`GenerateOptions.resolve`).
        points : int
            Points the pipeline gets (after the service's reduction of a big cloud).

        Returns
        -------
        Estimate
            Levers: ``points`` (reference: the encoder's count), ``samples`` (1),
            ``steps`` (the model's), ``start_time`` (the model's), ``target_vertices``
            (the model's count) and ``tolerance`` (none), those set above it.
        """
        def formula(changes: Mapping[str, float | None]) -> tuple[float, float]:
            changed: dict[str, Any] = {k: v for k, v in changes.items() if k != "points"}
            for name in ("samples", "steps", "target_vertices"):
                if changed.get(name) is not None:
                    changed[name] = int(changed[name])
            varied = replace(options, **changed)
            count = int(changes.get("points", points) or points)
            return self._generate(spec, varied, count)

        seconds, memory = formula({})
        return Estimate(seconds, memory, _generate_levers(spec, options, points), formula)

    def _generate(self, spec: ModelSpec, options: GenerateOptions, points: int
                  ) -> tuple[float, float]:
        # the seeds expected to run, never fewer than a request of fewer samples's (the
        # retry seeds top a request up to 1 + retry_seeds, so 2 samples expect fewer than 1)
        expected_seeds = float(options.samples) if options.raw else max(
            k + spec.retries_for(k) * self.retry_chance ** k
            for k in range(1, options.samples + 1))
        prepare = self.prepare_s_per_point * points
        base_mb = (self.report_mb_per_point * min(points, REPORT_POINTS)
                   + self.points_mb * points)
        if options.face_type == "polygons":  # once, on the chosen mesh
            prepare += self.polygons_s2 * float(_final_count(spec, options)) ** 2
        if options.tolerance is None or options.start != "points":
            seconds, memory = self._seeds(spec, options, points, expected_seeds)
            return prepare + seconds + self._fewer(spec, options, points), base_mb + memory
        tries = self.tolerance_tries(spec, float(options.tolerance))
        seconds, memory = 0.0, 0.0
        for count in tries:
            attempt = replace(options, tolerance=None, target_vertices=count)
            try_s, try_mb = self._seeds(spec, attempt, points, options.samples)
            seconds += try_s + self._fewer(spec, attempt, points)
            memory = max(memory, try_mb)
        found = replace(options, tolerance=None, target_vertices=tries[-1])
        retry_s, retry_mb = self._seeds(spec, found, points,
                                        expected_seeds - options.samples)
        return prepare + seconds + retry_s, base_mb + max(memory, retry_mb)

    def _seeds(self, spec: ModelSpec, options: GenerateOptions, points: int, seeds: float
               ) -> tuple[float, float]:
        """Seconds and MB of ``seeds`` seeds with ``options`` (no tolerance)."""
        wanted = _final_count(spec, options)
        if options.start == "points":
            dense = decode_count(spec, options)  # ``wanted`` for raw or without one
            tokens = network_vertices(dense, spec.max_vertices, spec.large_meshes,
                                      raw=options.raw)
            start = float(options.start_time or 0.0)
        else:  # from noise the network places the model's tokens and picks the count
            dense = tokens = spec.max_vertices
            start = 1.0
        steps = denoiser_steps(spec, sampler_key(options))
        n, v, d = float(tokens), float(wanted), float(dense)
        geometry = self.geometry_s0 + self.geometry_s1 * v + self.geometry_s2 * v * v
        if d > v:  # a dense decode: fitted at its count, collapsed to ``v``, fitted again
            geometry += (self.geometry_s1 * d + self.geometry_s2 * d * d
                         + self.collapse_s * (d - v))
        slower = 1 + self.denoised_slowdown * start
        per_seed = (
            (self.fps_s_per_point * points + self.fps_s_per_token * n
             if options.start == "points" else 0.0)
            + steps * (self.step_s1 * n + self.step_s2 * n * n)
            + self.connect_s * n
            + slower * (self.decode_s2 * n * n + geometry)
            + self.report_s_per_point * min(points, REPORT_POINTS)
            + self.report_s_per_vertex * v
        )
        memory = (self.tokens_mb * (1 + self.denoised_tokens_mb * start) * n * n
                  + self.vertex_mb * v + self.seed_mb_per_token * n * seeds)
        return seeds * per_seed, memory

    def _fewer(self, spec: ModelSpec, options: GenerateOptions, points: int) -> float:
        """Seconds a request's mesh made again from fewer vertices is expected to add
        (at ``fewer_chance``): the request at the fewer count, then the geometry stage
        at the count asked for."""
        fewer = fewer_vertices(spec, options) if spec.retry_seeds else None
        if fewer is None:
            return 0.0
        lower = replace(options, target_vertices=fewer)
        seeds = options.samples + spec.retries_for(options.samples) * self.retry_chance
        seconds, _ = self._seeds(spec, lower, points, seeds)
        v = float(vertex_count(spec, options))
        geometry = self.geometry_s0 + self.geometry_s1 * v + self.geometry_s2 * v * v
        return self.fewer_chance * (seconds + geometry)

    def tolerance_tries(self, spec: ModelSpec, tolerance: float) -> list[int]:
        """The vertex counts a ``tolerance`` search is counted as, the found count last.

        At most :data:`~spacemesh.runtime.tolerance.MAX_TRIES` generates: the doubling
        ladder of :func:`~spacemesh.runtime.tolerance.search_vertex_count` from the
        model's count up to the first count whose mesh is expected within the aim (a mean
        distance of ``tolerance_scale / count``), and the other tries at that count (the
        search halves or bisects below it, so no try is larger). An upper bound that
        grows as the tolerance shrinks.
        """
        start = min(max(spec.vertices, MIN_SEARCH_VERTICES), MAX_SEARCH_VERTICES)
        wanted = min(math.ceil(self.tolerance_scale / aim(tolerance)), MAX_SEARCH_VERTICES)
        counts = [start]
        while counts[-1] < wanted:
            counts.append(min(2 * counts[-1], MAX_SEARCH_VERTICES))
        return counts + [counts[-1]] * (MAX_TRIES - len(counts))

    # ------------------------------------------------------------------ repair
    def repair(self, spec: ModelSpec, *, steps: int, faces: int, passes: int = 1,
               fills: int = 0, fill_vertices2: float = 0.0, automatic: bool = False
               ) -> Estimate:
        """The estimate of a repair.

        Parameters
        ----------
        spec : ModelSpec
        steps : int
            Its sampler steps (resolved).
        faces : int
            Faces of the mesh (after a weld).
        passes : int
            Model passes: 1 for a marked region; for an automatic one, a pass per region
            re-generated whole and per wedge of each hole filled in place
            (:attr:`spacemesh.repair.auto.AutoPlan.model_passes`).
        fills : int
            Regions of holes refined, faired and probed after their passes.
        fill_vertices2 : float
            The sum over their holes of the squared number of vertices of each.
        automatic : bool
            An automatic region (the whole mesh oriented and searched).

        Returns
        -------
        Estimate
            Levers: ``steps`` (the model's), ``region`` (one pass, its fills in
            proportion) and ``mesh`` (no face).
        """
        def formula(changes: Mapping[str, float | None]) -> tuple[float, float]:
            d = float(changes.get("steps", steps) or steps)
            p = float(changes.get("region", passes) or passes)
            f = float(changes.get("mesh", faces) or 0)
            share = p / passes if passes else 0.0  # of the fills, with fewer passes
            samplings = sum(self.retry_chance ** k for k in range(REPAIR_SAMPLINGS))
            per_pass = (self.repair_step_s * d * spec.max_vertices / 256
                        + self.repair_pass_s)
            filling = share * (fills * (self.repair_fill_s + self.repair_fill_s_per_face * f)
                               + self.repair_fill_s_per_vertex2 * fill_vertices2)
            per_face = self.repair_s_per_face + (self.repair_auto_s_per_face if automatic
                                                 else 0.0)
            return (samplings * p * per_pass + filling + per_face * f,
                    self.repair_mb + self.repair_mb_per_face * f)

        seconds, memory = formula({})
        levers = [Lever("steps", steps, spec.steps, 1), Lever("region", passes, 1, 1),
                  Lever("mesh", faces, 0, 0)]
        return Estimate(seconds, memory, tuple(x for x in levers if x.costly), formula)


def _generate_levers(spec: ModelSpec, options: GenerateOptions, points: int
                     ) -> tuple[Lever, ...]:
    """The levers of a generate request (those set above their reference)."""
    levers = [Lever("points", points, min(points, spec.n_points), spec.n_points),
              Lever("samples", options.samples, 1, 1),
              Lever("steps", int(options.steps or spec.steps), spec.steps, 1)]
    if options.start == "points":
        levers.append(Lever("start_time", float(options.start_time or 0.0), spec.start_time,
                            spec.start_time, integer=False))
        if options.target_vertices is not None:
            levers.append(Lever("target_vertices", options.target_vertices, None,
                                MIN_TARGET_VERTICES))
        if options.tolerance is not None:
            levers.append(Lever("tolerance", float(options.tolerance), None, MAX_TOLERANCE,
                                integer=False, raise_to_save=True))
    return tuple(x for x in levers if x.costly)


#: The calibrated model (``bench/bench_cost_model.py``).
DEFAULT_COST_MODEL = CostModel()

__all__ = ["DEFAULT_COST_MODEL", "CostModel", "Estimate", "Formula", "Lever"]
