"""The network stages of one group of seeds: encoder, sampler, connectivity, decode, and
per mesh the geometry stage and the fit report.

Seeds that share sampler settings (:func:`sampler_key`) run as one group: each network
call takes the whole group as one batch (one item per seed; the backend runs each item
alone, so a seed's mesh never depends on its group, see
:class:`spacemesh.runtime.backend.OnnxBackend`).
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from spacemesh.decode import DecodeResult, Embeddings, decode
from spacemesh.geometry import farthest_point_sampling
from spacemesh.geometry.finishing import finish_geometry, outward
from spacemesh.geometry.pieces import drop_fragments
from spacemesh.geometry.surface import shape_surface
from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.backend import Backend, ConnectivityOutputs, denoiser_fn
from spacemesh.runtime.large import needs_split, network_vertices
from spacemesh.runtime.options import MIN_TARGET_VERTICES, GenerateOptions
from spacemesh.runtime.request import GenerateResult, PreparedInput
from spacemesh.runtime.sampler import ProgressFn, StageFn, sample, split_tokens, start_steps
from spacemesh.runtime.spec import DUPLICATE_TOLERANCE, ModelSpec
from spacemesh.runtime.tolerance import simplify_distance
from spacemesh.topology import surface_topology
from spacemesh.typed import FloatArray

#: The sampler settings that let seeds share network calls:
#: ``(steps, sampler, start, start_time)``.
SamplerKey = tuple[int, str, str, float]


def sampler_key(options: GenerateOptions) -> SamplerKey:
    """The group of resolved ``options`` (seeds with equal keys share network calls)."""
    start_time = 1.0 if options.start_time is None else float(options.start_time)
    assert options.steps is not None  # resolved options (GenerateOptions.resolve)
    return int(options.steps), str(options.sampler), str(options.start), start_time


def denoiser_steps(spec: ModelSpec, key: SamplerKey) -> int:
    """Denoiser calls of a group with sampler settings ``key``."""
    steps, _, start, start_time = key
    respaced = spec.schedule.respaced(steps)
    return len(respaced) if start == "noise" else start_steps(respaced, start_time)


def vertex_count(spec: ModelSpec, options: GenerateOptions) -> int:
    """Vertices ``start=points`` chooses: the target, else the model's default."""
    return int(options.target_vertices or spec.vertices)


def decode_count(spec: ModelSpec, options: GenerateOptions) -> int:
    """Vertices the decode makes for ``options``: :func:`vertex_count`, or more with the
    model's dense decode (:attr:`spacemesh.geometry.GeometryOptions.dense_factor`; not
    with ``raw``), which the geometry stage simplifies back to :func:`vertex_count`."""
    wanted = vertex_count(spec, options)
    return wanted if options.raw else spec.geometry.decode_vertices(wanted)


def fewer_vertices(spec: ModelSpec, options: GenerateOptions) -> int | None:
    """The vertex count a mesh whose faces still cross after every other mend is made
    again from, before its edges are split back up to :func:`vertex_count`
    (:meth:`spacemesh.runtime.MeshGenerator._from_fewer`): the model's default count
    when the request asks for more (no output at that count crossed on any evaluation
    set), else half the count; None with ``raw``, from noise (the network picks the
    count), or below :data:`MIN_TARGET_VERTICES` (a tetrahedron cannot cross)."""
    if options.raw or options.start != "points":
        return None
    wanted = vertex_count(spec, options)
    fewer = spec.vertices if wanted > spec.vertices else wanted // 2
    return fewer if fewer >= MIN_TARGET_VERTICES else None


def plain_spec(spec: ModelSpec) -> ModelSpec:
    """``spec`` without its dense decode: every request decodes the count it asks for."""
    if spec.geometry.dense_factor <= 1:
        return spec
    return replace(spec, geometry=replace(spec.geometry, dense_factor=1.0))


def drop_duplicates(positions: FloatArray, alive: np.ndarray,
                    tolerance: float = DUPLICATE_TOLERANCE) -> np.ndarray:
    """``alive`` without the later vertex of every pair closer than ``tolerance``.

    Parameters
    ----------
    positions : (N, 3)
    alive : (N,) bool
    tolerance : float

    Returns
    -------
    (N,) bool
    """
    from scipy.spatial import cKDTree

    alive = np.asarray(alive, dtype=bool).copy()
    index = np.flatnonzero(alive)
    if index.size < 2:
        return alive
    pairs = cKDTree(positions[index]).query_pairs(tolerance, output_type="ndarray")
    if len(pairs):
        alive[index[pairs.max(axis=1)]] = False
    return alive


def start_tokens(spec: ModelSpec, jobs: list[tuple[PreparedInput, GenerateOptions]]
                 ) -> np.ndarray:
    """Clean tokens ``(B, N, 4)`` of the farthest-point vertices of each job's
    normalised cloud (real tokens first, padding after with mask -1)."""
    chosen = []
    for prepared, options in jobs:
        wanted = network_vertices(decode_count(spec, options), spec.max_vertices,
                                  spec.large_meshes, raw=options.raw)
        pick = farthest_point_sampling(prepared.unit, wanted, seed=options.seed,
                                       weights=prepared.weights)
        chosen.append(prepared.unit[pick])
    n = max([spec.max_vertices, *(len(c) for c in chosen)])
    tokens = np.zeros((len(jobs), n, 4), dtype=np.float32)
    tokens[..., 3] = -1.0
    for b, c in enumerate(chosen):
        tokens[b, : len(c), :3] = c
        tokens[b, : len(c), 3] = 1.0
    return tokens


def decode_item(spec: ModelSpec, positions: np.ndarray, emb: ConnectivityOutputs, b: int,
                alive: np.ndarray, prepared: PreparedInput) -> DecodeResult:
    """Decode batch item ``b`` of the connectivity outputs ``emb`` (positions
    ``(N, 3)``, alive ``(N,)``)."""
    embeddings = Embeddings(
        np.asarray(emb.x[b], np.float64), emb.tau, np.asarray(emb.root[b], np.float64),
        np.asarray(emb.prev[b], np.float64), np.asarray(emb.next[b], np.float64),
    )
    return decode(positions.astype(np.float64), embeddings, spec.decode,
                  alive=alive, points=prepared.cloud[:, :3])


def _decode_prefix(backend: Backend, spec: ModelSpec, positions: np.ndarray,
                   alive: np.ndarray, volumes: list[np.ndarray], b: int, count: int,
                   prepared: PreparedInput) -> DecodeResult:
    """Decode job ``b``'s first ``count`` tokens alone (the connectivity network run
    again on them): farthest-point sampling is greedy, so they are the tokens a request
    for ``count`` vertices gets (positions ``(B, N, 3)``, alive ``(B, N)``)."""
    emb = backend.connect(positions[b:b + 1, :count], alive[b:b + 1, :count],
                          [v[b:b + 1] for v in volumes])
    return decode_item(spec, positions[b, :count], emb, 0, alive[b, :count], prepared)


def _genus(mesh: PolygonMesh) -> int:
    """The genus of a decode without its fragments (what the geometry stage keeps)."""
    return surface_topology(drop_fragments(mesh)[0]).genus


def geometry_targets(spec: ModelSpec, options: GenerateOptions, unit: FloatArray
                     ) -> tuple[int | None, float | None]:
    """What a seed's geometry stage reduces its decode to: ``target_vertices`` (the
    count asked for, with ``start=points``) and ``max_distance`` (with a ``tolerance``,
    :func:`spacemesh.runtime.tolerance.simplify_distance` on the fit points ``unit``)."""
    points_start = options.start == "points"  # resolved options
    within = (simplify_distance(options.tolerance, unit)
              if options.tolerance is not None and points_start else None)
    return (vertex_count(spec, options) if points_start else None), within


def run_group(backend: Backend, spec: ModelSpec,
              jobs: list[tuple[PreparedInput, GenerateOptions]], key: SamplerKey,
              progress: ProgressFn, stage: StageFn) -> list[GenerateResult]:
    """Every job's mesh: the networks once for the whole group, then per job the
    decode, the geometry stage (not with ``raw``) and the fit report.

    Parameters
    ----------
    backend : Backend
    spec : ModelSpec
    jobs : list of (PreparedInput, GenerateOptions)
        One seed each (resolved options), all with sampler settings ``key``.
    key : SamplerKey
    progress : callable
        ``progress(done, total)`` after each denoiser step.
    stage : callable
        ``stage(name, done, total)`` as each stage begins.

    Returns
    -------
    list of GenerateResult
        In job order; ``timings`` has the job's share of the group's network times and
        its own decode, geometry and report times.
    """
    _, method, start, start_time = key
    stage("encoder", 1, 1)
    t0 = time.perf_counter()
    points = np.stack([prepared.cloud for prepared, _ in jobs])  # (B, P, C)
    volumes = backend.encode(points)
    t1 = time.perf_counter()
    clean = start_tokens(spec, jobs) if start == "points" else None
    n_tokens = spec.max_vertices if clean is None else clean.shape[1]
    stage("sampler", 0, denoiser_steps(spec, key))
    tokens = sample(
        denoiser_fn(backend, volumes, points if spec.local_points else None),
        seeds=[options.seed for _, options in jobs], n_vertices=n_tokens,
        steps=spec.schedule.respaced(key[0]), method=method, progress=progress,
        start=clean, start_time=start_time,
    )
    positions, alive = split_tokens(tokens)  # (B, N, 3), (B, N)
    spacing = spec.vertex_spacing if start == "noise" else DUPLICATE_TOLERANCE
    alive = np.stack([drop_duplicates(p, a, spacing)
                      for p, a in zip(positions, alive, strict=True)])
    t2 = time.perf_counter()
    stage("connectivity", 1, 1)
    emb = backend.connect(positions, alive, volumes)
    t3 = time.perf_counter()
    results = []
    for b, (prepared, options) in enumerate(jobs):
        stage("decode", b + 1, len(jobs))
        e0 = time.perf_counter()
        decoded = decode_item(spec, positions[b], emb, b, alive[b], prepared)
        m = spec.max_vertices
        if (start == "points" and not options.raw
                and needs_split(int(alive[b].sum()), decoded.mesh.n_vertices, m)):
            # the full-token graph fell apart: the model's own token count instead
            alive[b, m:] = False
            decoded = _decode_prefix(backend, spec, positions, alive, volumes, b, m, prepared)
            decoded.stats["large_meshes"] = "split"
        wanted = vertex_count(spec, options)
        if (start == "points" and not options.raw and decode_count(spec, options) > wanted
                and decoded.stats.get("large_meshes") != "split"):
            # a dense decode: kept only if it has no more handles than the decode of the
            # count asked for (its farthest-point prefix), which a denser graph can add;
            # one without handles is kept without decoding the other, and so is one for a
            # count below the model's own, where the plain decode loses handles instead
            # (docs/GEOMETRY.md, "Compact meshes")
            dense_genus = _genus(decoded.mesh)
            plain_genus = None
            if dense_genus > 0 and wanted >= spec.vertices:
                plain = _decode_prefix(backend, spec, positions, alive, volumes, b, wanted,
                                       prepared)
                plain_genus = _genus(plain.mesh)
                if plain_genus < dense_genus:
                    decoded = plain
            decoded.stats["dense_genus"] = [dense_genus, plain_genus]
        mesh = outward(decoded.mesh)
        e1 = time.perf_counter()
        geometry_stats: dict[str, Any] = {}
        surface = None  # raw: the closed decode, no decision
        unfitted = None
        if not options.raw:
            stage("geometry", b + 1, len(jobs))
            unit, normals = prepared.fit_points()
            target, within = geometry_targets(spec, options, unit)
            unfitted = mesh
            mesh, geometry_stats = finish_geometry(mesh, unit, normals, spec.geometry,
                                                   target_vertices=target, max_distance=within)
            # last: trimming only removes faces, and the seeds' checks see the result
            mesh, surface, trimmed = shape_surface(mesh, unit, normals, str(options.surface),
                                                   spec.geometry)
            geometry_stats.update(trimmed)
        mesh = prepared.to_upload(mesh)
        e2 = time.perf_counter()
        stage("report", b + 1, len(jobs))
        report = prepared.report(mesh, surface)
        share = len(jobs)  # the group's network calls count a share for each job
        timings = {"encoder": (t1 - t0) / share, "sampler": (t2 - t1) / share,
                   "connectivity": (t3 - t2) / share, "extraction": e1 - e0,
                   "geometry": e2 - e1, "report": time.perf_counter() - e2}
        timings["total"] = sum(timings.values())
        results.append(GenerateResult(
            mesh=mesh, options=options, timings=timings,
            n_sampled_vertices=int(alive[b].sum()), decode_stats=dict(decoded.stats),
            geometry_stats=geometry_stats, fit=report,
            # an open surface's second candidate starts from its decode (pipeline)
            decoded=unfitted if surface is not None and surface.open else None,
        ))
    return results


__all__ = ["SamplerKey", "decode_count", "decode_item", "denoiser_steps", "drop_duplicates",
           "geometry_targets", "plain_spec", "run_group", "sampler_key", "start_tokens",
           "vertex_count"]
