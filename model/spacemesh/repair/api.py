"""``repair_mesh``: re-generate the vertices and faces of a marked region of a mesh.

The data flow (docs/REPAIR.md)::

    mesh + region
      -> (weld=True) vertices at equal positions merged, region mapped spacemesh.repair.weld
      -> cut (grow until no pinched hole; defects outside -> 422)     spacemesh.repair.cut
      -> patch: region + rings of kept faces, renormalised            spacemesh.repair.patch
      -> conditioning points on the patch's original surface -> encoder
      -> inpainting sampler, known vertices held                      spacemesh.repair.inpaint
      -> new vertices: free tokens alive by the mask, in the hole
      -> connectivity network on known + new vertices
      -> fill: edges new-new and new-boundary, fans spliced           spacemesh.repair.splice
      -> new vertices fitted to the region's original surface         spacemesh.geometry
      -> (every sampling crossed) crossing new faces mended         spacemesh.repair.crossings
      -> (still crossing) region grown by the faces crossed, again  spacemesh.repair.regrow
      -> mesh: kept faces unchanged, new faces appended

The same three networks as generation (numpy + onnxruntime; no torch, no retraining).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.decode import Embeddings
from spacemesh.geometry import refine_geometry
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import fan_volumes, triangles_of
from spacemesh.primitives.closest import nearest_triangles
from spacemesh.repair.auto import AutoPlan, plan_auto, repair_auto
from spacemesh.repair.crossings import new_crossings, uncross_polygons
from spacemesh.repair.cut import Cut, cut_region
from spacemesh.repair.fill.kinds import FilledBy, FillKind
from spacemesh.repair.fill.loops import patch_euler
from spacemesh.repair.fill.policy import DEFAULT_POLICY, FillPolicy
from spacemesh.repair.findings import MAX_REPORTED
from spacemesh.repair.inpaint import InpaintResult, inpaint_tokens
from spacemesh.repair.patch import (
    MAX_RINGS,
    Patch,
    PatchSamples,
    hole_surface,
    in_hole,
    plan_patch,
    sample_patch,
    sub_mesh,
)
from spacemesh.repair.region import (
    DEFAULT_MAX_GROWTH,
    REGION_GROWTH_EXCEEDED,
    Region,
    RegionError,
    parse_region,
)
from spacemesh.repair.regrow import refill_crossings, regrow_crossings
from spacemesh.repair.result import RepairResult, RepairStats, new_face_degrees
from spacemesh.repair.splice import Spliced, fill_hole, splice
from spacemesh.repair.weld import weld_region, weld_vertices
from spacemesh.runtime.backend import Backend, ConnectivityOutputs
from spacemesh.runtime.network import drop_duplicates
from spacemesh.runtime.pipeline import MeshGenerator
from spacemesh.runtime.sampler import ProgressFn
from spacemesh.runtime.schedule import METHODS
from spacemesh.runtime.spec import ModelSpec
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Hole points sampled per free token (the first ``N - K`` pad the alignment; all of
#: them decide which generated vertices are in the hole).
HOLE_POINTS_PER_TOKEN = 4


@dataclass(frozen=True)
class RepairPlan:
    """The model-independent part of a repair: the cut and the patch.

    :func:`plan_repair` raises every :class:`spacemesh.repair.region.RegionError` a
    repair can raise, without running a network, so a service can answer 422 before
    queueing the request.

    Attributes
    ----------
    cut : Cut
        The region cut out of the input, or out of its weld (``weld=True``).
    patch : Patch
    hole : PolygonMesh
    seconds : float
        Time spent planning (welding included).
    source : PolygonMesh or None
        The input mesh the plan was made for (None: ``cut.mesh``).
    weld_map : (V,) int64 or None
        With ``weld=True``: the index in ``cut.mesh`` of each input vertex
        (:func:`spacemesh.repair.weld.weld_vertices`); None without.
    """

    cut: Cut
    patch: Patch
    hole: PolygonMesh
    seconds: float = 0.0
    source: PolygonMesh | None = None
    weld_map: IntArray | None = None

    @property
    def input_mesh(self) -> PolygonMesh:
        """The mesh the plan was made for."""
        return self.cut.mesh if self.source is None else self.source

    @property
    def welded_vertices(self) -> int:
        """Input vertices merged away by the weld (0 without ``weld=True``)."""
        return 0 if self.weld_map is None else len(self.weld_map) - self.cut.mesh.n_vertices


def verify_repair(plan: RepairPlan | AutoPlan, result: RepairResult) -> list[str]:
    """What a repair changed beyond the grown region (empty when nothing).

    The faces a repair may change are exactly the plan's grown region
    (``plan.cut.region``, computed before any network ran), and the faces a region still
    crossing was grown by (:mod:`spacemesh.repair.regrow`; counted in the stats'
    ``fill["regrown_faces"]``, the plan's region kept whole; for an automatic plan, its
    fills re-generated as a region, :func:`spacemesh.repair.regrow.refill_crossings`):
    every other input face must
    come back first, in input order, as the same polygon on the same positions (same
    cycle, same first corner), and only new faces may follow. A server runs this on
    every repair before it answers, so a faulty repair is refused, never returned.

    Parameters
    ----------
    plan : RepairPlan or AutoPlan
        The plan the repair ran with. For an automatic plan the faces that may change
        are its regions after growth (:attr:`AutoPlan.changeable`; a region filled by
        the fan changes none), compared with its working mesh (welded and oriented).
    result : RepairResult

    Returns
    -------
    list of str
        One sentence per violation.
    """
    out, face_source = result.mesh, np.asarray(result.face_source)
    issues: list[str] = []
    if isinstance(plan, AutoPlan):
        source, region = plan.mesh, np.asarray(result.region, dtype=bool)
        regrown = int(result.stats.fill.get("regrown_faces", 0))
        if (region.shape != plan.changeable.shape
                or int((region & ~plan.changeable).sum()) > regrown):
            issues.append("the repair removed faces outside the planned regions (and the"
                          " growth around its crossings it reports)")
            return issues
    else:
        source, region = plan.cut.mesh, np.asarray(result.region, dtype=bool)
        regrown = int(result.stats.fill.get("regrown_faces", 0))
        if (region.shape != plan.cut.region.shape or (plan.cut.region & ~region).any()
                or int(region.sum() - plan.cut.region.sum()) != regrown):
            issues.append("the repair reports another region than the plan's grown region"
                          " (and the growth around its crossings it reports)")
            return issues
    if len(face_source) != out.n_faces:
        return [*issues, f"{len(face_source)} face sources for {out.n_faces} faces"]
    expected = np.flatnonzero(~region)
    n_kept = len(expected)
    kept = face_source >= 0
    if not (int(kept.sum()) == n_kept and kept[:n_kept].all()
            and np.array_equal(face_source[:n_kept], expected)):
        inside = np.unique(face_source[kept & (face_source < len(region))])
        dropped = np.setdiff1d(expected, face_source[kept])
        grown = inside[region[inside]] if len(inside) else inside
        issues.append(f"the kept faces are not the {n_kept} input faces outside the grown "
                      f"region in order ({len(dropped)} of them missing, "
                      f"{len(grown)} region faces kept)")
        return issues
    if not np.array_equal(out.face_sizes[:n_kept], source.face_sizes[expected]):
        changed = np.flatnonzero(out.face_sizes[:n_kept] != source.face_sizes[expected])
        return [*issues, f"{len(changed)} faces outside the grown region changed their "
                f"number of corners (input face {int(expected[changed[0]])} first)"]
    in_corners = source.face_indices[~region[source.face_of_corner]]
    out_corners = out.face_indices[: out.face_offsets[n_kept]]
    moved = np.any(out.vertices[out_corners] != source.vertices[in_corners], axis=1)
    if moved.any():
        faces = np.unique(out.face_of_corner[: len(out_corners)][moved])
        issues.append(f"{len(faces)} faces outside the grown region changed (input face "
                      f"{int(expected[faces[0]])} first)")
    return issues


def check_growth(cut: Cut, max_growth: float) -> None:
    """Refuse a region that growth took beyond ``max_growth`` of the mesh's faces.

    Raises
    ------
    RegionError
        ``region-growth-exceeded`` with ``share``, ``max_growth``, ``requested_faces``,
        ``region_faces`` and ``faces``.
    """
    n_faces = cut.mesh.n_faces
    share = float(cut.region.sum()) / max(n_faces, 1)
    if cut.n_grown > 0 and share > max_growth:
        raise RegionError(
            REGION_GROWTH_EXCEEDED,
            f"the region of {int(cut.requested.sum())} faces grows to {int(cut.region.sum())} "
            f"faces ({share:.0%} of the mesh's {n_faces}; at most {max_growth:.0%} allowed) "
            "because the vertices around it are pinched: mark a region without pinched "
            "corners, or allow more with max_growth",
            {"share": round(share, 4), "max_growth": max_growth,
             "requested_faces": int(cut.requested.sum()),
             "region_faces": int(cut.region.sum()), "faces": n_faces})


def _max_growth(value: float | None) -> float:
    value = DEFAULT_MAX_GROWTH if value is None else float(value)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"max_growth must be in 0..1, not {value}")
    return value


def plan_repair(mesh: PolygonMesh, region: Region | Mapping[str, Any] | BoolArray,
                n_tokens: int, *, max_rings: int = MAX_RINGS, weld: bool = False,
                max_growth: float | None = None, tolerated: BoolArray | None = None
                ) -> RepairPlan | AutoPlan:
    """Cut the region and choose the patch (no network runs).

    Parameters
    ----------
    mesh : PolygonMesh
    region : Region, dict (JSON form) or (F,) bool face mask
        In ``mesh``'s indices (also with ``weld``).
    n_tokens : int
        The model's vertex tokens (``ModelSpec.max_vertices``).
    max_rings : int
        Most rings of kept faces around the region.
    weld : bool
        Merge vertices at exactly equal positions first and repair the welded mesh
        (:mod:`spacemesh.repair.weld`); vertex indices of the region are mapped.
    max_growth : float, optional
        Largest share (0..1) of the mesh's faces the region may grow to
        (:func:`check_growth`; default :data:`DEFAULT_MAX_GROWTH`).
    tolerated : (V,) bool, optional
        Vertices whose defects may stay outside the region (the other regions of an
        automatic repair; :func:`spacemesh.repair.cut.outside_defects`).

    Returns
    -------
    RepairPlan or AutoPlan
        An :class:`~spacemesh.repair.auto.AutoPlan` for an ``{"auto": ...}`` region.

    Raises
    ------
    RegionError
        With ``kind`` one of ``invalid-region``, ``empty-region``,
        ``whole-mesh-region``, ``defects-outside-region``, ``region-too-large``,
        ``region-growth-exceeded``, ``non-orientable`` (automatic regions).
    ValueError
        ``max_growth`` outside 0..1.
    """
    start = time.perf_counter()
    max_growth = _max_growth(max_growth)
    if not isinstance(region, np.ndarray):
        shape = parse_region(region)
        if shape.is_auto:
            return plan_auto(mesh, str(shape.mode), n_tokens, plan_region=plan_repair,
                             weld=weld, max_growth=max_growth)
    work, weld_map = mesh, None
    if weld:
        work, weld_map = weld_vertices(mesh)
        region = weld_region(region, weld_map)
    cut = cut_region(work, region, tolerated)
    check_growth(cut, max_growth)
    hole = hole_surface(cut)
    patch = plan_patch(cut, n_tokens, max_rings=max_rings, hole=hole)
    return RepairPlan(cut, patch, hole, time.perf_counter() - start, mesh, weld_map)


def enclosed_volume(mesh: PolygonMesh) -> float:
    """Signed volume of the faces, each fanned from its first corner (O(corners)).

    Positive when the faces wind counter-clockwise seen from outside. Exact for planar
    polygons of any shape; for open meshes it still tells the dominant orientation.
    """
    return float(fan_volumes(mesh).sum())


def select_new_vertices(result: InpaintResult, samples: PatchSamples, max_new: int
                        ) -> tuple[IntArray, BoolArray, dict[str, int]]:
    """The free tokens that become new vertices.

    A free token alive by the mask channel is kept when its nearest patch sample is a
    hole point (not a kept-face point) and it is not within the pipeline's duplicate
    tolerance of a known vertex or of another kept token. At most ``max_new`` are kept,
    those with the largest mask channel: a mask that keeps more tokens alive than the
    density around the hole implies is trusted only for its most confident tokens.

    Returns
    -------
    candidates : (M,) int64
        Token indices of the new vertices.
    valid : (N,) bool
        Known tokens and candidates (the connectivity network's mask).
    counts : dict
        ``alive``, ``outside_hole`` and ``duplicates``.
    """
    positions = result.tokens[:, :3].astype(np.float64)  # (N, 3)
    alive = np.flatnonzero(result.alive)
    inside_mask = in_hole(positions[alive], samples)
    inside = alive[inside_mask]
    order = np.concatenate([result.known_token, inside])  # known first: duplicates drop new
    kept = drop_duplicates(positions[order], np.ones(len(order), dtype=bool))
    distinct = inside[kept[len(result.known_token):]]
    confident = np.argsort(-result.tokens[distinct, 3], kind="stable")[:max(max_new, 0)]
    candidates = np.sort(distinct[confident])
    valid = ~result.free
    valid[candidates] = True
    counts = {"alive": len(alive), "outside_hole": int((~inside_mask).sum()),
              "duplicates": len(inside) - len(distinct),
              "over_limit": len(distinct) - len(candidates)}
    return candidates, valid, counts


def hole_embeddings(out: ConnectivityOutputs, rows: IntArray, flipped: bool) -> Embeddings:
    """The embeddings of the tokens ``rows`` (boundary vertices, then new vertices).

    With ``flipped`` (a clockwise input) ``prev`` and ``next`` swap roles, which reverses
    every predicted cyclic order.
    """
    prev, nxt = (out.next, out.prev) if flipped else (out.prev, out.next)
    return Embeddings(np.asarray(out.x[0][rows], np.float64), out.tau,
                      np.asarray(out.root[0][rows], np.float64),
                      np.asarray(prev[0][rows], np.float64),
                      np.asarray(nxt[0][rows], np.float64))


def _resolve(generator: MeshGenerator | None, backend: Backend | None,
             spec: ModelSpec | None) -> tuple[Backend, ModelSpec]:
    if generator is not None:
        return generator.backend, generator.spec
    if backend is not None and spec is not None:
        return backend, spec
    if backend is not None or spec is not None:
        raise ValueError("pass both backend and spec, or a MeshGenerator")
    default = MeshGenerator.from_repository()
    return default.backend, default.spec


def _sampler_options(spec: ModelSpec, steps: int | None, method: str | None) -> tuple[int, str]:
    steps = spec.steps if steps is None else int(steps)
    method = spec.method if method is None else str(method)
    if method not in METHODS:
        raise ValueError(f"unknown sampler {method!r}; choose from {', '.join(METHODS)}")
    if not 1 <= steps <= spec.schedule.timesteps:
        raise ValueError(f"steps must be in 1..{spec.schedule.timesteps}, not {steps}")
    return steps, method


def surface_normals(points: FloatArray, surface: PolygonMesh) -> FloatArray:
    """``(P, 3)`` unit normals of the faces of ``surface`` nearest to ``points``."""
    triangles, _ = triangles_of(surface)
    owner, _ = nearest_triangles(points, surface.vertices, triangles)
    corners = surface.vertices[triangles[owner]]  # (P, 3, 3)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    return normal / np.where(length > 0, length, 1.0)


def fit_new_vertices(spliced: Spliced, points: FloatArray, normals: FloatArray,
                     spec: ModelSpec) -> PolygonMesh:
    """The spliced mesh with its new vertices fitted to ``points`` (the region's original
    surface and its surroundings, with that surface's ``normals``) by the geometry
    stage; every kept vertex stays fixed and no face changes, so everything outside the
    region is untouched.

    The stage runs on the new faces and the kept faces around them only, so its cost
    does not grow with the mesh (the self-intersection guard sees that neighbourhood).
    """
    mesh = spliced.mesh
    n_kept = mesh.n_vertices - spliced.n_new_vertices
    face = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    touching = np.zeros(mesh.n_faces, dtype=bool)
    touching[face[mesh.face_indices >= n_kept]] = True
    near = np.zeros(mesh.n_vertices, dtype=bool)
    near[mesh.face_indices[touching[face]]] = True
    local_faces = np.flatnonzero(np.bincount(face, near[mesh.face_indices], mesh.n_faces) > 0)
    local = sub_mesh(mesh, local_faces)
    local, ids = local.remove_unreferenced_vertices()
    refined = refine_geometry(local, points, normals, spec.geometry, fixed=ids < n_kept)
    vertices = mesh.vertices.copy()
    vertices[ids] = refined.mesh.vertices
    return mesh.with_vertices(vertices)


#: Samplings tried for a region whose fill has a lower Euler characteristic than the
#: region's faces (a handle spliced in: 4 of 48 random regions on the dev split,
#: experiments/check_repair_genus.py) or whose new faces cross a face (6 of 27 dev
#: regions, experiments/repair_crossings.py); the seed's own sampling first.
TOPOLOGY_ATTEMPTS = 3


def repair_mesh(
    mesh: PolygonMesh,
    region: Region | Mapping[str, Any] | BoolArray,
    generator: MeshGenerator | None = None,
    *,
    backend: Backend | None = None,
    spec: ModelSpec | None = None,
    seed: int = 0,
    steps: int | None = None,
    method: str | None = None,
    progress: ProgressFn | None = None,
    plan: RepairPlan | AutoPlan | None = None,
    weld: bool = False,
    fit_patch: bool = True,
    max_growth: float | None = None,
    policy: FillPolicy = DEFAULT_POLICY,
    regrow: bool = True,
) -> RepairResult:
    """Re-generate the vertices and faces of ``region`` (paper Sec. 5.5, Supplement D).

    Parameters
    ----------
    mesh : PolygonMesh
        Any polygon mesh; its defects (open boundaries, non-manifold edges, pinched
        vertices) must lie in the region.
    region : Region, dict or (F,) bool
        See :mod:`spacemesh.repair.region`.
    generator : MeshGenerator, optional
        The model; or pass ``backend`` and ``spec``; default: the shipped model.
    backend : Backend, optional
    spec : ModelSpec, optional
    seed : int
        The same seed gives the same mesh.
    steps : int, optional
        Sampler steps (default: the model's).
    method : {"ddim", "ddpm"}, optional
        Sampler (default: the model's).
    progress : callable, optional
        ``progress(done, total)`` after each denoiser step.
    plan : RepairPlan or AutoPlan, optional
        From :func:`plan_repair` (computed when None), made with the same ``weld``.
    weld : bool
        Merge vertices at exactly equal positions (split at UV seams, hard edges) before
        the cut, and repair the welded mesh (:mod:`spacemesh.repair.weld`). Without it,
        such a mesh is open along every seam.
    fit_patch : bool
        Fit the new vertices to the region's original surface with the geometry stage
        (:func:`spacemesh.geometry.refine_geometry`, kept vertices fixed, no edge
        edits, self-intersections never increased), and for automatic regions of holes
        refine and fair each filling into the surface around it, or replace it
        (:func:`spacemesh.repair.fill.finish.finish_holes`); False gives the networks'
        patch.
    max_growth : float, optional
        Largest share of the mesh's faces a region may grow to (see :func:`plan_repair`;
        the plan's when one is given).
    policy : FillPolicy
        How automatic regions of holes are filled once the model's passes are done
        (:class:`spacemesh.repair.fill.policy.FillPolicy`; the default is the one the docs
        report); its ``euler`` also tells whether a sampling's fill added a handle.
    regrow : bool
        A marked region whose new faces still cross once every sampling crossed and the
        mending is done is grown around the crossings and repaired again
        (:func:`spacemesh.repair.regrow.regrow_crossings`; its stats say so). An
        automatic region's fills that still cross once it is finished are made again as
        a marked region (:func:`spacemesh.repair.regrow.refill_crossings`). Both only
        with ``fit_patch``.

    Returns
    -------
    RepairResult
        Faces outside the region are unchanged; a closed manifold input gives a closed
        manifold output.

    Raises
    ------
    RegionError
        See :func:`plan_repair`.
    ValueError
        Bad ``steps`` or ``method``, or a plan made for another mesh, model or ``weld``.
    """
    t_start = time.perf_counter()
    plan_given = plan is not None
    backend, spec = _resolve(generator, backend, spec)
    steps, method = _sampler_options(spec, steps, method)
    if plan is None:
        plan = plan_repair(mesh, region, spec.max_vertices, weld=weld, max_growth=max_growth)
    else:
        n_tokens = plan.n_tokens if isinstance(plan, AutoPlan) else plan.patch.n_tokens
        if plan.input_mesh is not mesh or n_tokens != spec.max_vertices:
            raise ValueError("the plan was made for another mesh or model")
        if (plan.weld_map is not None) != bool(weld):
            raise ValueError(f"the plan was made with weld={plan.weld_map is not None}")
    if isinstance(plan, AutoPlan):
        return _repair_automatic(plan, backend, spec, seed=int(seed), steps=steps,
                                 method=method, progress=progress, fit_patch=fit_patch,
                                 started=t_start, policy=policy, regrow=regrow)
    cut, patch = plan.cut, plan.patch
    mesh = cut.mesh  # the input, or its weld
    timings = {"cut": plan.seconds}

    expected_euler = patch_euler(mesh, cut.region)
    n_pad = patch.n_tokens - len(patch.known)
    known_unit = patch.to_unit(mesh.vertices[patch.known])  # (K, 3)
    flipped = bool(enclosed_volume(mesh) < 0)
    fewest: tuple[Any, ...] | None = None
    for attempt in range(TOPOLOGY_ATTEMPTS):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        t0 = time.perf_counter()
        rng = np.random.default_rng(int(seed) if attempt == 0 else [int(seed), attempt])
        samples = sample_patch(cut, patch, n_points=spec.n_points, normals=spec.normals,
                               n_hole=max(HOLE_POINTS_PER_TOKEN * n_pad, 64), rng=rng,
                               hole=plan.hole)
        timings["patch"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        volumes = backend.encode(samples.condition[None])
        timings["encoder"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        result = inpaint_tokens(backend, volumes, known_unit, samples.hole[:n_pad],
                                spec.schedule.respaced(steps), method=method, rng=rng,
                                progress=progress,
                                points=samples.condition[None] if spec.local_points else None)
        positions = result.tokens[:, :3].astype(np.float64)  # (N, 3)
        candidates, valid, dropped = select_new_vertices(result, samples, patch.expected_new)
        timings["sampler"] = time.perf_counter() - t0

        checkpoint()
        t0 = time.perf_counter()
        out = backend.connect(positions[None].astype(np.float32), valid[None], volumes)
        timings["connectivity"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        boundary_tokens = result.known_token[np.searchsorted(patch.known, cut.boundary)]
        emb = hole_embeddings(out, np.concatenate([boundary_tokens, candidates]), flipped)
        fill = fill_hole(emb, len(cut.boundary), cut.loop_next, cut.loop_prev, spec.decode)
        spliced = splice(cut, patch.from_unit(positions[candidates]), fill)
        timings["splice"] = time.perf_counter() - t0

        drop = expected_euler - policy.euler(spliced.mesh, spliced.face_source < 0)

        checkpoint()
        t0 = time.perf_counter()
        if fit_patch and spliced.n_new_vertices:
            cloud = patch.from_unit(np.concatenate([samples.hole, samples.kept]))
            kept = patch.faces[~cut.region[patch.faces]]
            surface = PolygonMesh.from_faces(plan.hole.vertices,
                                             plan.hole.faces + sub_mesh(mesh, kept).faces)
            spliced = replace(spliced, mesh=fit_new_vertices(
                spliced, cloud, surface_normals(cloud, surface), spec))
        timings["geometry"] = time.perf_counter() - t0
        # of the fitted patch, what the user gets (the networks' own patch is not judged)
        crossing = new_crossings(spliced) if fit_patch else 0
        rank = (max(drop, 0), crossing)  # the fewest handles, then the fewest crossings
        if fewest is None or rank < fewest[0]:
            fewest = (rank, drop, candidates, dropped, fill, spliced)
        if drop <= 0 and crossing == 0:
            break  # no handle spliced in (a handle lowers the Euler characteristic by 2)
            # and no new face crossing
    assert fewest is not None  # set by the first of the TOPOLOGY_ATTEMPTS (at least one)
    (_, crossing), drop, candidates, dropped, fill, spliced = fewest
    fill_stats = dict(fill.stats)
    if crossing:  # every sampling crossed: its crossing polygons triangulated again
        t0 = time.perf_counter()
        spliced, fill_stats["uncrossed_faces"] = uncross_polygons(spliced, plan.hole)
        timings["uncross"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start + (plan.seconds if plan_given else 0.0)

    fs = fill_stats
    fallback = ("polygon" if fs["polygon_loops"] else
                "removed-new-vertices" if fs["n_unpinched"] or fs["n_detached"] else "none")
    stats = RepairStats(
        requested_faces=int(cut.requested.sum()), region_faces=int(cut.region.sum()),
        grown_faces=cut.n_grown, removed_vertices=len(cut.removed_vertices),
        boundary_vertices=len(cut.boundary), loops=len(cut.loops),
        new_vertices=spliced.n_new_vertices, new_faces=spliced.n_new_faces,
        new_face_degrees=new_face_degrees(spliced.mesh, spliced.face_source < 0),
        patch_faces=len(patch.faces), patch_rings=patch.rings,
        known_vertices=len(patch.known), tokens=patch.n_tokens, candidates=len(candidates),
        fallback=fallback, fill=dict(fs),
        inpaint=dropped,
        flipped_orientation=flipped, welded_vertices=plan.welded_vertices,
        region_share=round(float(cut.region.sum()) / max(mesh.n_faces, 1), 4),
        samplings=attempt + 1, handles_added=max(drop, 0) // 2, seed=int(seed),
        steps=steps, method=method, timings=timings,
    )
    vertex_map = spliced.vertex_map if plan.weld_map is None else (
        spliced.vertex_map[plan.weld_map])
    repaired = RepairResult(spliced.mesh, vertex_map, spliced.face_source, cut.region, stats)
    if not (regrow and crossing):
        return repaired
    return regrow_crossings(plan.input_mesh, repaired, lambda grown: repair_mesh(
        plan.input_mesh, grown, backend=backend, spec=spec, seed=seed, steps=steps,
        method=method, progress=progress, weld=weld, fit_patch=fit_patch,
        max_growth=max_growth, policy=policy, regrow=False))


_FALLBACK_RANK = ("none", "removed-new-vertices", "polygon", FillKind.FAN.value,
                  FillKind.MESHFIX.value)


def _repair_automatic(plan: AutoPlan, backend: Backend, spec: ModelSpec, *, seed: int,
                      steps: int, method: str, progress: ProgressFn | None, fit_patch: bool,
                      started: float, policy: FillPolicy = DEFAULT_POLICY,
                      regrow: bool = True) -> RepairResult:
    """Run the passes of an automatic plan (:func:`spacemesh.repair.auto.repair_auto`)
    and put their results together; pass ``k`` uses the seed ``seed + k``."""
    def run_pass(mesh: PolygonMesh, faces: BoolArray, tolerated: BoolArray,
                 allowed: BoolArray, index: int) -> RepairResult:
        checkpoint()  # every pass
        step = plan_repair(mesh, faces, spec.max_vertices, max_growth=plan.max_growth,
                           tolerated=tolerated)
        assert isinstance(step, RepairPlan)  # a face mask is never an automatic region
        if (step.cut.region & ~allowed).any():
            raise RegionError(REGION_GROWTH_EXCEEDED, "the pass grows beyond its planned "
                              "region")
        return repair_mesh(mesh, faces, backend=backend, spec=spec, seed=seed + index,
                           steps=steps, method=method, progress=progress, plan=step,
                           fit_patch=fit_patch, policy=policy, regrow=False)

    state, findings, regions = repair_auto(plan, run_pass, fair=fit_patch, policy=policy)
    passes = list(state.passes)
    out, work = state.mesh, plan.mesh
    new = state.face_source < 0
    kept_vertices = np.unique(state.vertex_map[state.vertex_map >= 0])
    removed = np.ones(work.n_faces, dtype=bool)
    removed[state.face_source[~new]] = False

    def total(name: str) -> int:
        return int(sum(getattr(p, name) for p in passes))

    def summed(name: str) -> dict[str, Any]:
        out_dict: dict[str, Any] = {}
        for p in passes:
            for key, value in getattr(p, name).items():
                out_dict[key] = out_dict.get(key, 0) + value
        return out_dict

    worst = [p.fallback for p in passes] + [
        (FillKind.MESHFIX if r["filled_by"] == FilledBy.MESHFIX else FillKind.FAN).value
        for r in regions if r["filled_by"] != FilledBy.MODEL]
    timings = summed("timings")
    timings["cut"] = timings.get("cut", 0.0) + plan.seconds
    timings["total"] = time.perf_counter() - started
    requested = sum(int(r.requested.sum()) for r in plan.regions if r.strategy == "model")
    stats = RepairStats(
        requested_faces=requested, region_faces=int(removed.sum()),
        grown_faces=sum(r.grown_faces for r in plan.regions),
        removed_vertices=work.n_vertices - len(kept_vertices),
        boundary_vertices=total("boundary_vertices"), loops=total("loops"),
        new_vertices=out.n_vertices - len(kept_vertices), new_faces=int(new.sum()),
        new_face_degrees=new_face_degrees(out, new),
        patch_faces=total("patch_faces"),
        patch_rings=max([p.patch_rings for p in passes], default=0),
        known_vertices=total("known_vertices"), tokens=spec.max_vertices,
        candidates=total("candidates"),
        fallback=max(worst, key=_FALLBACK_RANK.index, default="none"),
        fill=summed("fill"), inpaint=summed("inpaint"),
        flipped_orientation=any(p.flipped_orientation for p in passes),
        welded_vertices=plan.welded_vertices,
        region_share=max([r["share"] for r in regions], default=0.0),
        auto_region=plan.mode, passes=len(passes),
        reversed_faces=int(plan.reversed_faces.sum()),
        flipped_mesh=bool(plan.reversed_faces.size and plan.reversed_faces.all()),
        samplings=total("samplings"), handles_added=total("handles_added"),
        findings=findings[:MAX_REPORTED], findings_total=len(findings),
        regions=regions[:MAX_REPORTED], seed=seed, steps=steps, method=method,
        timings=timings,
    )
    # the working mesh's vertices after the input's are copies made by unzip_defects
    vertex_map = (state.vertex_map[:plan.source.n_vertices] if plan.weld_map is None
                  else state.vertex_map[plan.weld_map])
    repaired = RepairResult(out, vertex_map, state.face_source, removed, stats)
    if not (fit_patch and regrow):
        return repaired
    return refill_crossings(repaired, lambda region: repair_mesh(
        out, region, backend=backend, spec=spec, seed=seed, steps=steps, method=method,
        progress=progress, fit_patch=fit_patch, policy=policy))
