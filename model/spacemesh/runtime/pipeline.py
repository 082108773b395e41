"""Point cloud in, oriented manifold polygon mesh out: :class:`MeshGenerator`, which
drives the stages of a request.

For each request:

1. set the outliers aside and measure the noise (:mod:`spacemesh.geometry.cleaning`),
   then normalise the rest and pick the encoder's points (:mod:`spacemesh.runtime.request`);
2. per group of seeds (:mod:`spacemesh.runtime.network`): encoder, sampler, connectivity
   network, :func:`spacemesh.decode.decode` (a valid oriented manifold mesh, faces
   flipped outward), the geometry stage and the fit report;
3. the seed whose mesh passes the topology check and fits best
   (:mod:`spacemesh.runtime.choice`), more seeds when none passes, its crossing faces
   untangled (:mod:`spacemesh.geometry.untangle`); an open surface gets a second
   candidate, its decode trimmed to the points before the geometry stage, and the better
   of the two is kept (:meth:`MeshGenerator._trimmed_first`); when its points form a flat
   sheet, a third, decoded as a slab (:meth:`MeshGenerator._flat_slab`);
4. with ``tolerance``: a search over vertex counts (:mod:`spacemesh.runtime.tolerance`).

Each seed's mesh gets its ``surface`` at the end of its geometry stage (trimmed to the
points with ``surface=open``, or ``auto`` deciding so: :mod:`spacemesh.geometry.surface`),
so the seeds' checks and the untangling see what the user gets; with
``face_type=polygons`` the chosen mesh's flat regions are merged into planar polygons
last (:mod:`spacemesh.geometry.polygons`).

Requests of one :meth:`MeshGenerator.generate_batch` call share each network call;
each keeps its own seed, and the backend runs every batch item alone, so batching never
changes a result. This module uses numpy and onnxruntime only (never torch).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh.geometry import FitReport, GeometryOptions, SurfaceFacts
from spacemesh.geometry.finishing import finish_geometry, fit_trimmed_first
from spacemesh.geometry.hull import hull_mesh
from spacemesh.geometry.polygons import collapse_flat, merge_coplanar
from spacemesh.geometry.sheet import slab_points
from spacemesh.geometry.surface import drop_crossing_faces, shape_surface
from spacemesh.geometry.untangle import untangle
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_manifold
from spacemesh.runtime.backend import Backend
from spacemesh.runtime.choice import acceptable, best_fit, crosses, fit_score_of
from spacemesh.runtime.network import (
    SamplerKey,
    decode_count,
    denoiser_steps,
    fewer_vertices,
    geometry_targets,
    plain_spec,
    run_group,
    sampler_key,
    vertex_count,
)
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.repository import ModelRepository
from spacemesh.runtime.request import (
    GenerateRequest,
    GenerateResult,
    PreparedInput,
    prepare_input,
    summed_timings,
)
from spacemesh.runtime.sampler import ProgressFn, StageFn
from spacemesh.runtime.spec import ModelSpec
from spacemesh.runtime.tolerance import (
    MAX_TRIES,
    aim,
    attempt_options,
    distance_of,
    most_vertices,
    search_vertex_count,
)
from spacemesh.typed import FloatArray

#: ``face_type=polygons``: the largest distance of a polygon's corner from its plane, a
#: fraction of the points' diagonal (the promise is 0.1%; a margin for rounding).
POLYGON_PLANARITY = 0.0009


class MeshGenerator:
    """Generates meshes from point clouds with one model.

    Parameters
    ----------
    backend : Backend
        The three networks (onnxruntime, or torch for comparisons).
    spec : ModelSpec
    name : str
        Reported by the service.
    """

    def __init__(self, backend: Backend, spec: ModelSpec, *, name: str = "spacemesh") -> None:
        self.backend = backend
        self.spec = spec
        self.name = name
        self.repository: ModelRepository | None = None  # set by from_repository

    @classmethod
    def from_repository(
        cls, path: str | Path | None = None, *, threads: int = 0,
    ) -> MeshGenerator:
        """Load a model repository (default: the shipped model) into a generator.

        Parameters
        ----------
        path : path, optional
            See :meth:`spacemesh.runtime.repository.ModelRepository.load`.
        threads : int
            Threads that run the networks' batch items at once (0: one per core); the
            meshes do not depend on it (:class:`~spacemesh.runtime.backend.OnnxBackend`).

        Returns
        -------
        MeshGenerator
        """
        repo = ModelRepository.load(path, threads=threads)
        generator = cls(repo.backend, ModelSpec.from_manifest(repo.manifest), name=repo.name)
        generator.repository = repo
        return generator

    # ------------------------------------------------------------------ public API
    def generate(
        self,
        points: FloatArray,
        normals: FloatArray | None = None,
        options: GenerateOptions | None = None,
        *,
        progress: ProgressFn | None = None,
        stage: StageFn | None = None,
        **fields: Any,
    ) -> GenerateResult:
        """Generate one mesh.

        Parameters
        ----------
        points : (P, 3) float
            Conditioning points in any frame and scale.
        normals : (P, 3) float, optional
            Used by the geometry stage (estimated when absent), and needed by models
            whose encoder reads normals.
        options : GenerateOptions, optional
            Default: the model's defaults with seed 0.
        progress : callable, optional
            ``progress(done, total)`` after each denoiser step.
        stage : callable, optional
            ``stage(name, done, total)`` as each stage begins (see
            :meth:`generate_batch`).
        **fields
            :class:`~spacemesh.runtime.options.GenerateOptions` fields by name (e.g.
            ``seed=3, raw=True``), applied over ``options``.

        Returns
        -------
        GenerateResult

        Raises
        ------
        OptionError
            An option out of range.
        ValueError
            Points (or normals) that cannot be used.
        """
        options = replace(options or GenerateOptions(), **fields)
        request = GenerateRequest(points, normals, options)
        return self.generate_batch([request], progress=progress, stage=stage)[0]

    def generate_batch(
        self, requests: Sequence[GenerateRequest], *, progress: ProgressFn | None = None,
        stage: StageFn | None = None,
    ) -> list[GenerateResult]:
        """Generate several meshes, sharing each network call.

        Requests with different sampler settings (steps, sampler, start, start time)
        run as separate groups; a request with ``samples = K`` runs its K seeds in its
        group and keeps the best-fitting mesh. A request with a ``tolerance`` runs on
        its own, after the others, as a search over vertex counts
        (:mod:`spacemesh.runtime.tolerance`; its stage events include ``tolerance``,
        the ``done``-th of at most ``total`` tries).

        Parameters
        ----------
        requests : sequence of GenerateRequest
        progress : callable, optional
            ``progress(done, total)`` over the denoiser steps of all groups.
        stage : callable, optional
            ``stage(name, done, total)`` as each stage begins: ``encoder``, ``sampler``
            (0 of its ``total`` denoiser steps done; ``progress`` follows), then ``decode``,
            ``geometry`` (not with ``raw``) and ``report`` for the ``done``-th of
            ``total`` meshes of the group (a request with ``samples = K`` makes K).
            Reporting never changes a result.

        Returns
        -------
        list of GenerateResult
            In request order.

        Raises
        ------
        OptionError
            An option out of range (before any network runs).
        """
        resolved = [r.options.resolve(self.spec) for r in requests]
        # each request's points once, shared by its seeds and tries (fails before any work)
        inputs = [self.prepare_input(r, o) for r, o in zip(requests, resolved, strict=True)]
        plain = [i for i, options in enumerate(resolved) if options.tolerance is None]
        found = self._generate_prepared([(inputs[i], resolved[i]) for i in plain],
                                        progress, stage)
        results: list[GenerateResult | None] = [None] * len(requests)
        for index, result in zip(plain, found, strict=True):
            results[index] = result
        for index, options in enumerate(resolved):
            if options.tolerance is not None:  # searched after the others
                results[index] = self._within_tolerance(inputs[index], options, progress,
                                                        stage)
        return [result for result in results if result is not None]

    def _generate_prepared(
        self, items: Sequence[tuple[PreparedInput, GenerateOptions]],
        progress: ProgressFn | None, stage: StageFn | None, *, retry: bool = True,
        dense: bool = True,
    ) -> list[GenerateResult]:
        """:meth:`generate_batch` on prepared inputs with resolved options (no
        ``tolerance``): the best fit of each request's seeds, in request order.

        With a model whose :attr:`ModelSpec.retry_seeds` is set, a mesh with as many
        pieces as the points (:func:`spacemesh.geometry.pieces.point_pieces`) is
        preferred to any without, then one whose faces do not cross; when none of a
        request's seeds has both, more seeds run, up to ``1 + retry_seeds`` in all
        (:meth:`ModelSpec.retries_for`; stage ``pieces``; not with ``retry`` False) before
        choosing (:func:`spacemesh.runtime.choice.best_fit`).

        With the model's dense decode (``dense``; :attr:`GeometryOptions.dense_factor`), a
        chosen mesh whose faces still cross after the untangling gives way to the decode
        at the count asked for (all of the above again, ``dense`` False) when that one
        does not cross: a denser graph can tangle thin parts that the plain one leaves
        apart, and no output may cross.
        """
        spec = self.spec if dense else plain_spec(self.spec)
        results = []
        for (prepared, options), tried in zip(items, self._seed_results(items, progress,
                                                                         stage, spec),
                                              strict=True):
            expected = prepared.pieces
            if (retry and spec.retries_for(options.samples) and not options.raw
                    and not any(acceptable(r, expected) for r in tried)):
                tried += self._retry_seeds(prepared, options, progress, stage, spec)
            spent = summed_timings(tried)  # every seed ran: the request spent them all
            chosen = best_fit(tried, options, expected, check=spec.retry_seeds > 0)
            chosen.timings = spent
            chosen = self._untangled(chosen, prepared, stage)
            chosen = self._trimmed_first(chosen, prepared, stage, spec)
            chosen = self._flat_slab(chosen, prepared, progress, stage)
            if (spec.retry_seeds and crosses(chosen)
                    and decode_count(spec, options) > vertex_count(spec, options)):
                plain = self._generate_prepared([(prepared, options)], progress, stage,
                                                retry=retry, dense=False)[0]
                plain.timings = summed_timings([chosen, plain])  # both ran
                if not crosses(plain):
                    results.append(plain)
                    continue
                chosen.timings = plain.timings
            if spec.retry_seeds and crosses(chosen):
                chosen = self._from_fewer(chosen, prepared, options, progress, stage,
                                          retry=retry)
            results.append(self._faced(chosen, prepared))
        return results

    def _from_fewer(self, chosen: GenerateResult, prepared: PreparedInput,
                    options: GenerateOptions, progress: ProgressFn | None,
                    stage: StageFn | None, *, retry: bool) -> GenerateResult:
        """A chosen mesh whose faces still cross after every other mend, made again from
        fewer vertices: the same request at :func:`fewer_vertices` (a ``tolerance``
        request's at that count alone; its seeds, retries, untangling and, when that one
        crosses too, this again with fewer still), then its edges split up to the count
        asked for and fitted (:func:`finish_geometry`). The
        geometry stage's guard lets no fitted face cross that the split mesh did not, and
        splitting a mesh that does not cross makes none, so the result does not cross
        (stage ``fewer``; its timings count every run; ``geometry_stats`` gives
        ``fewer_vertices``). ``chosen`` is kept when no count is left to try or the
        fewer-vertex mesh crosses too or is an open surface (a closed mesh's is made
        closed again; an open one has its crossing faces dropped instead)."""
        count = vertex_count(self.spec, options)
        fewer = fewer_vertices(self.spec, options)
        surface = _decided(chosen.fit) if chosen.fit is not None else None
        closed = surface is not None and not surface.open  # the same decision below
        if fewer is None:
            if closed and options.start == "points" and not options.raw:
                return self._hull_instead(chosen, prepared, count, surface, stage)
            return chosen
        if stage is not None:
            stage("fewer", 1, 1)
        lower_options = replace(options, target_vertices=fewer, tolerance=None,
                                face_type="triangles",
                                surface="closed" if closed else options.surface)
        lower = self._generate_prepared([(prepared, lower_options)], progress, stage,
                                        retry=retry)[0]
        lower.timings = summed_timings([chosen, lower])  # both ran
        lower_surface = _decided(lower.fit) if lower.fit is not None else None
        if crosses(lower) or lower_surface is None or lower_surface.open:
            chosen.timings = lower.timings
            return chosen
        started = time.perf_counter()
        mesh, stats = _refitted(lower.mesh, prepared, plain_spec(self.spec).geometry,
                                target_vertices=count)
        lower.mesh = mesh
        lower.fit = prepared.report(mesh, lower_surface)
        lower.options = replace(options, seed=lower.seed)
        lower.geometry_stats = {**lower.geometry_stats, "fewer_vertices": fewer,
                                "fewer_split": int(stats.get("n_split", 0)),
                                "fewer_kept": bool(stats.get("kept", False))}
        _add_geometry_time(lower, time.perf_counter() - started)
        return lower

    def _hull_instead(self, chosen: GenerateResult, prepared: PreparedInput, count: int,
                      surface: SurfaceFacts | None, stage: StageFn | None) -> GenerateResult:
        """The last resort of :meth:`_from_fewer`, below the fewest vertices a request may
        ask for: the convex hull of the fit points (:func:`spacemesh.geometry.hull.
        hull_mesh`, at most ``count`` corners), its edges split up to ``count`` and fitted
        (stage ``hull``; ``geometry_stats["convex_hull"]``). A convex polyhedron does not
        cross, and neither the split nor the guarded fit makes a crossing. ``chosen`` is
        kept where the points span no volume."""
        points, _ = prepared.fit_points()  # (P, 3) in the normalised frame
        hull = hull_mesh(points, count)
        if hull is None:
            return chosen
        if stage is not None:
            stage("hull", 1, 1)
        started = time.perf_counter()
        hull = prepared.to_upload(hull)
        mesh, stats = _refitted(hull, prepared, plain_spec(self.spec).geometry,
                                target_vertices=count)
        chosen.mesh = mesh
        chosen.fit = prepared.report(mesh, surface)
        chosen.geometry_stats = {**chosen.geometry_stats, "convex_hull": True,
                                 "hull_split": int(stats.get("n_split", 0)),
                                 "hull_kept": bool(stats.get("kept", False))}
        _add_geometry_time(chosen, time.perf_counter() - started)
        return chosen

    def _untangled(self, result: GenerateResult, prepared: PreparedInput,
                   stage: StageFn | None) -> GenerateResult:
        """With the model's topology check on (:attr:`ModelSpec.retry_seeds`), the
        chosen mesh's crossing faces smoothed apart (:func:`untangle`, stage
        ``untangle``), fitted to the points again (:func:`finish_geometry`, whose guard
        lets no face cross that the untangling freed; smoothing alone can pull a folded
        mesh far from the points; not an open surface, which has no outside to orient
        by) and its fit report made for the new mesh, with the same surface decision. An
        open surface whose faces still cross loses them
        (:func:`spacemesh.geometry.surface.drop_crossing_faces`: its faces are only where
        points support them, and a crossing face is not a surface the points saw).
        ``raw`` results are left alone."""
        if (not self.spec.retry_seeds or result.options.raw or result.fit is None
                or not crosses(result)):
            return result
        if stage is not None:
            stage("untangle", 1, 1)
        started = time.perf_counter()
        surface = _decided(result.fit)
        opened = surface is not None and surface.open
        mesh, stats = untangle(result.mesh)
        if stats["crossing_after"] >= stats["crossing_before"]:
            mesh = result.mesh  # smoothing did not help
        elif not opened:  # an open mesh has no outside to refit to
            mesh, refit_stats = _refitted(mesh, prepared, self.spec.geometry)
            stats["untangle_refit_kept"] = bool(refit_stats.get("kept", False))
        if opened and stats["crossing_after"] > 0:
            mesh, stats["crossing_faces_dropped"] = drop_crossing_faces(mesh)
        if mesh is result.mesh:
            _add_geometry_time(result, time.perf_counter() - started)
            return result
        result.mesh = mesh
        result.geometry_stats = {**result.geometry_stats, **stats}
        result.fit = prepared.report(mesh, surface)
        _add_geometry_time(result, time.perf_counter() - started)
        return result

    def _trimmed_first(self, chosen: GenerateResult, prepared: PreparedInput,
                       stage: StageFn | None, spec: ModelSpec) -> GenerateResult:
        """An open surface's second candidate, made from the chosen seed's decode
        trimmed to the points before the geometry stage
        (:func:`spacemesh.geometry.finishing.fit_trimmed_first`, stage ``surface``) and
        untangled as the first was (:meth:`_untangled`); the better of the two is kept:
        one whose faces do not cross, then the better fit score (on the dev split's
        one-sided scans each candidate wins on about half the shapes, and the choice
        beats both; docs/GEOMETRY.md, "Open surfaces").
        ``geometry_stats["surface_trimmed_first"]`` says which was kept."""
        decoded, chosen.decoded = chosen.decoded, None  # used once, then freed
        if decoded is None or chosen.fit is None or chosen.options.raw:
            return chosen
        if stage is not None:
            stage("surface", 1, 1)
        started = time.perf_counter()
        unit, normals = prepared.fit_points()
        target, within = geometry_targets(spec, chosen.options, unit)
        made = fit_trimmed_first(decoded, unit, normals, spec.geometry,
                                 target_vertices=target, max_distance=within)
        chosen.geometry_stats = {**chosen.geometry_stats, "surface_trimmed_first": False}
        if made is None:
            _add_geometry_time(chosen, time.perf_counter() - started)
            return chosen
        unit_mesh, stats = made
        mesh = prepared.to_upload(unit_mesh)
        other = replace(chosen, mesh=mesh, fit=prepared.report(mesh, _decided(chosen.fit)),
                        geometry_stats={**stats, "surface_trimmed_first": True},
                        timings=dict(chosen.timings))
        _add_geometry_time(other, time.perf_counter() - started)
        return self._better(chosen, other, prepared, stage)

    def _flat_slab(self, chosen: GenerateResult, prepared: PreparedInput,
                   progress: ProgressFn | None, stage: StageFn | None) -> GenerateResult:
        """An open surface whose points form a flat sheet gets one more candidate: the
        points and a copy pushed back behind their plane
        (:func:`spacemesh.geometry.sheet.slab_points`), decoded closed (the same
        request otherwise, triangles: its seeds, retries and untangling), trimmed to the
        points and fitted to them (:func:`shape_surface`), then untangled; kept when it
        ranks better (:func:`_rank`). About half the slab's vertices are on the side
        the points face, so the candidate has about half the count asked for.
        ``geometry_stats["surface_slab"]`` says whether it was kept; its timings count
        both runs. A cloud of more than ``MAX_FIT_POINTS`` points gives the slab the
        fixed subset the fit uses (:meth:`PreparedInput.fit_subset`), so the slab's
        request stays small."""
        options = chosen.options
        if (chosen.fit is None or options.raw or not chosen.fit.open_surface
                or self.spec.normals or chosen.mesh.n_faces == 0):
            return chosen
        sheet = prepared.fit_subset(prepared.points)  # (<= MAX_FIT_POINTS, 3)
        slab = slab_points(sheet, chosen.mesh.vertex_normals().sum(axis=0))
        if slab is None:
            return chosen
        if stage is not None:
            stage("surface", 1, 1)
        slab_options = replace(options, surface="closed", face_type="triangles")
        closed = self._generate_prepared(
            [(self.prepare_input(GenerateRequest(slab, None, slab_options), slab_options),
              slab_options)], progress, stage)[0]
        started = time.perf_counter()
        unit, normals = prepared.fit_points()
        trimmed, facts, stats = shape_surface(prepared.to_unit(closed.mesh), unit, normals,
                                              "open", self.spec.geometry)
        chosen.geometry_stats = {**chosen.geometry_stats, "surface_slab": False}
        timings = summed_timings([chosen, closed])  # both ran
        if not facts.open or trimmed.n_faces == 0:
            chosen.timings = timings
            _add_geometry_time(chosen, time.perf_counter() - started)
            return chosen
        mesh = prepared.to_upload(trimmed)
        other = replace(chosen, mesh=mesh, fit=prepared.report(mesh, _decided(chosen.fit)),
                        geometry_stats={**stats, "surface_slab": True}, timings=timings,
                        decode_stats=closed.decode_stats,
                        n_sampled_vertices=closed.n_sampled_vertices)
        _add_geometry_time(other, time.perf_counter() - started)
        return self._better(chosen, other, prepared, stage)

    def _better(self, chosen: GenerateResult, other: GenerateResult,
                prepared: PreparedInput, stage: StageFn | None) -> GenerateResult:
        """Of an open surface's chosen mesh and another candidate for it, the other
        untangled as the chosen one was (:meth:`_untangled`), the one that ranks better
        (:func:`_rank`); the chosen one keeps the other's timings (both ran)."""
        other = self._untangled(other, prepared, stage)
        if _rank(other) < _rank(chosen):
            return other
        chosen.timings = other.timings
        return chosen

    def _faced(self, result: GenerateResult, prepared: PreparedInput) -> GenerateResult:
        """The chosen mesh's faces as ``face_type`` asks, last (nothing after it moves a
        vertex): with ``polygons`` the edges collapsed that leave the surface where it
        was (:func:`spacemesh.geometry.polygons.collapse_flat`: flat regions lose their
        interior vertices, so the mesh has fewer vertices than asked for), then its flat
        regions merged into planar polygons
        (:func:`spacemesh.geometry.polygons.merge_coplanar`, every merged face's corners
        within :data:`POLYGON_PLANARITY` of the diagonal of its plane); with
        ``triangles`` a decode's polygons triangulated
        (:func:`spacemesh.primitives.triangulate_manifold`, as manifold as the
        polygons); its fit report made again when the faces changed."""
        if result.fit is None or result.options.raw:
            return result
        started = time.perf_counter()
        stats: dict[str, int | float] = {}
        merged = result.mesh
        if result.options.face_type == "polygons":
            tolerance = POLYGON_PLANARITY * result.fit.diagonal
            flat, stats = collapse_flat(result.mesh, tolerance)
            merged, merging = merge_coplanar(flat, tolerance)
            stats = {**stats, **merging}
        elif not result.mesh.is_triangle_mesh():
            vertices, triangles, _ = triangulate_manifold(result.mesh)
            merged = PolygonMesh(vertices, triangles.reshape(-1),
                                 np.arange(0, triangles.size + 1, 3))
            stats = {"faces_triangulated": result.mesh.n_faces}
        if merged is not result.mesh:
            result.mesh = merged
            result.fit = prepared.report(merged, _decided(result.fit))
        result.geometry_stats = {**result.geometry_stats, **stats}
        _add_geometry_time(result, time.perf_counter() - started)
        return result

    def _retry_seeds(self, prepared: PreparedInput, options: GenerateOptions,
                     progress: ProgressFn | None, stage: StageFn | None,
                     spec: ModelSpec | None = None) -> list[GenerateResult]:
        """The results of the model's retry seeds after a request's own
        (:meth:`ModelSpec.retries_for`; stage ``pieces``), with ``spec`` (default: the
        model's); none when the request's own seeds are as many."""
        spec = spec or self.spec
        count = spec.retries_for(options.samples)
        if count == 0:
            return []
        if stage is not None:
            stage("pieces", 1, 1)
        more = replace(options, seed=options.seed + options.samples, samples=count)
        return self._seed_results([(prepared, more)], progress, stage, spec)[0]

    def _seed_results(
        self, items: Sequence[tuple[PreparedInput, GenerateOptions]],
        progress: ProgressFn | None, stage: StageFn | None,
        spec: ModelSpec | None = None,
    ) -> list[list[GenerateResult]]:
        """Every seed's result of each request (``samples`` seeds from its ``seed``),
        the seeds of all requests grouped by sampler settings to share network calls,
        with ``spec`` (default: the model's)."""
        spec = spec or self.spec
        jobs: list[tuple[int, GenerateOptions]] = []  # (request index, one seed)
        for index, (_, options) in enumerate(items):
            jobs += [(index, replace(options, seed=options.seed + k))
                     for k in range(options.samples)]
        groups: dict[SamplerKey, list[int]] = {}
        for j, (_, options) in enumerate(jobs):
            groups.setdefault(sampler_key(options), []).append(j)
        total = sum(denoiser_steps(spec, key) for key in groups)
        outcomes: list[GenerateResult | None] = [None] * len(jobs)
        done = 0
        for key, members in groups.items():
            def report(step: int, _total: int, offset: int = done) -> None:
                if progress is not None:
                    progress(offset + step, total)

            batch = run_group(self.backend, spec,
                              [(items[jobs[j][0]][0], jobs[j][1]) for j in members],
                              key, report, stage or _no_stage)
            for j, result in zip(members, batch, strict=True):
                outcomes[j] = result
            done += denoiser_steps(spec, key)
        return [[r for j, (i, _) in enumerate(jobs) if i == index
                 for r in [outcomes[j]] if r is not None] for index in range(len(items))]

    def _within_tolerance(self, prepared: PreparedInput, options: GenerateOptions,
                          progress: ProgressFn | None, stage: StageFn | None
                          ) -> GenerateResult:
        """The smallest mesh within ``options.tolerance`` (resolved options), every try
        on the same prepared points.

        First one generate whose decode, fitted, is collapsed for as long as the points
        stay within the aim (:func:`simplify_distance`; the model's seeds, retries and
        mends as any generate), taken when its points are within the aim.
        Else a search over vertex counts (:func:`search_vertex_count`, the first try
        counted among its :data:`MAX_TRIES`, no count above the points'
        :func:`most_vertices`). The search's tries run without the model's
        retry seeds (the search's time); the count found gets them when its mesh fails
        the topology check, and a retry's mesh is taken only if it keeps the tolerance
        met. The mesh found is the one a generate at its count gives (untangled and faced
        once, as :meth:`_generate_prepared` finishes it); a retry seed's is finished
        likewise (an open surface's second candidate included)."""
        assert options.tolerance is not None
        tolerance = float(options.tolerance)
        if stage is not None:
            stage("tolerance", 1, MAX_TRIES)
        simplified = self._generate_prepared([(prepared, options)], progress, stage)[0]
        ran: list[GenerateResult] = [simplified]  # every try and retry, for the timings
        if distance_of(simplified) <= aim(tolerance):
            simplified.tolerance_tries = [(simplified.mesh.n_vertices,
                                           distance_of(simplified))]
            return simplified

        def run(count: int) -> GenerateResult:
            attempt = attempt_options(options, count)  # resolved: the request's are
            ran.append(self._generate_prepared([(prepared, attempt)], progress, stage,
                                               retry=False)[0])
            return ran[-1]

        def on_try(done: int, total: int) -> None:
            if stage is not None:
                stage("tolerance", done + 1, total + 1)

        found, _, tried = search_vertex_count(run, aim(tolerance), self.vertex_count(options),
                                              on_try=on_try, max_tries=MAX_TRIES - 1,
                                              most=most_vertices(len(prepared.unit)))
        tried = [(simplified.mesh.n_vertices, distance_of(simplified)), *tried]
        expected = prepared.pieces
        searched = found  # a generate's mesh: untangled and faced already
        if self.spec.retry_seeds and not acceptable(found, expected):
            keep_met = distance_of(found) <= tolerance
            retried = self._retry_seeds(prepared, found.options, progress, stage)
            ran += retried
            extra = [r for r in retried if distance_of(r) <= tolerance or not keep_met]
            found = best_fit([found, *extra], found.options, expected)
        found.timings = summed_timings(ran)
        if found is not searched:  # a retry seed's mesh, as its seed decoded it
            found = self._trimmed_first(self._untangled(found, prepared, stage), prepared,
                                        stage, self.spec)
            found = self._faced(found, prepared)
        # the fit reports carry the tolerance and whether it is met (PreparedInput)
        found.options = replace(found.options, tolerance=tolerance, target_vertices=None)
        found.tolerance_tries = tried
        return found

    # ------------------------------------------------------------------ helpers
    def prepare_points(
        self, points: FloatArray, normals: FloatArray | None
    ) -> tuple[np.ndarray, FloatArray, float]:
        """Encoder input ``(n_points, 3 or 6)`` float32 and the normalisation transform."""
        prepared = self.prepare_input(GenerateRequest(points, normals))
        return prepared.cloud, prepared.centre, prepared.scale

    def prepare_input(self, request: GenerateRequest,
                      options: GenerateOptions | None = None) -> PreparedInput:
        """:func:`spacemesh.runtime.request.prepare_input` with this model."""
        return prepare_input(request, self.spec, options)

    def vertex_count(self, options: GenerateOptions) -> int:
        """Vertices ``start=points`` chooses: the target, else the model's default."""
        return vertex_count(self.spec, options)


def _refitted(mesh: PolygonMesh, prepared: PreparedInput, options: GeometryOptions, *,
              target_vertices: int | None = None) -> tuple[PolygonMesh, dict[str, Any]]:
    """``mesh`` (in the upload's frame) through the geometry stage again
    (:func:`finish_geometry` on the request's fit points, in the normalised frame, edges
    split up to ``target_vertices`` when given), and its statistics."""
    points, normals = prepared.fit_points()
    refitted, stats = finish_geometry(prepared.to_unit(mesh), points, normals, options,
                                      target_vertices=target_vertices)
    return prepared.to_upload(refitted), stats


def _decided(fit: FitReport) -> SurfaceFacts | None:
    """The surface decision a fit report carries (None for ``raw``), for the report of
    the same request's mended mesh."""
    if fit.open_surface is None:
        return None
    return SurfaceFacts(bool(fit.open_surface), float(fit.unsupported_area or 0.0))


def _rank(result: GenerateResult) -> tuple[bool, float]:
    """How :meth:`MeshGenerator._better` ranks an open surface's candidates: one
    whose faces do not cross first, then the better fit score (as the seeds are ranked,
    :func:`spacemesh.runtime.choice.best_fit`)."""
    return crosses(result), fit_score_of(result)


def _add_geometry_time(result: GenerateResult, seconds: float) -> None:
    """Count ``seconds`` of geometry work (the untangling, the surface) in ``result``'s
    timings."""
    for name in ("geometry", "total"):
        result.timings[name] = result.timings.get(name, 0.0) + seconds


def _no_stage(name: str, done: int, total: int) -> None:
    """A :data:`~spacemesh.runtime.sampler.StageFn` that reports nowhere."""


__all__ = ["MeshGenerator"]
