"""The service's one implementation of "generate", shared by REST and gRPC.

:class:`Engine` owns the model (a :class:`~spacemesh.runtime.MeshGenerator`), the
:class:`~spacemesh_service.lanes.Lanes` (two batchers) and the metrics. A request goes
through

    decode input (thread) -> cost -> a lane's queue -> batch (the lane's inference thread)
      -> encode output (thread)

and comes back as a :class:`Reply`, or raises a :class:`~spacemesh_service.problems.Problem`.
Once the input is decoded, the request's cost is estimated (:mod:`spacemesh.runtime.cost`)
and one over the settings' budget is refused (422 ``too-expensive``) before it is queued;
the estimate also picks its lane (light or main).
Both servers are thin adapters around :meth:`Engine.generate`, which is why they accept
the same inputs, raise the same errors and return the same bytes.

:meth:`Engine.repair` is the same for a repair (:mod:`spacemesh.repair`):

    read mesh + region, (weld,) cut and plan, estimate the cost (thread; region errors and
      too-expensive: 422 before queueing; the deadline or a disconnect stops the planning)
      -> a lane's queue -> repair_mesh alone (its inference thread) -> encode output (thread)
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from spacemesh.cancel import Cancelled, cancel_scope
from spacemesh.io.limits import ReadLimits
from spacemesh.mesh import PolygonMesh
from spacemesh.repair import (
    AutoPlan,
    RegionError,
    RepairPlan,
    plan_repair,
    repair_mesh,
    verify_repair,
)
from spacemesh.repair.region import Region
from spacemesh.runtime.budget import CostError
from spacemesh.runtime.cost import DEFAULT_COST_MODEL, Estimate
from spacemesh.runtime.options import GenerateOptions, OptionError
from spacemesh.runtime.pipeline import MeshGenerator
from spacemesh.runtime.request import GenerateRequest
from spacemesh.runtime.sampler import StageFn
from spacemesh_service import problems as P
from spacemesh_service.batcher import Batcher, ProgressFn, QueueFull, ShuttingDown
from spacemesh_service.inputs import (
    INPUT_FORMATS,
    MESH_FORMATS,
    ParseSlots,
    UploadRules,
    read_limits,
    read_mesh_upload,
    read_region,
    validate_cloud,
)
from spacemesh_service.lanes import Lanes
from spacemesh_service.metrics import Metrics
from spacemesh_service.options import (
    GENERATE_ROUTE_OPTIONS,
    REPAIR_ROUTE_OPTIONS,
    RequestOptions,
    option_problem,
    reported_options,
    resolve_request,
)
from spacemesh_service.outputs import (
    MEDIA_TYPES,
    EncodedMesh,
    encode_mesh,
    finite_or_none,
    repair_headers,
    repair_summary,
    sample_scores_header,
    stats_headers,
    value_headers,
)
from spacemesh_service.problems import Problem
from spacemesh_service.settings import Settings

log = logging.getLogger("spacemesh.service")

#: ``parse(limits, rules) -> (points, normals, source, body_options, points_read)``, run in
#: a worker thread under :attr:`Engine.parsing`, ``limits`` being
#: :func:`~spacemesh_service.inputs.read_limits` and ``rules`` the
#: :class:`~spacemesh_service.inputs.UploadRules` of the settings; ``points_read`` is the
#: upload's point count when ``points`` are a reduction of it, else None.
ParseFn = Callable[[ReadLimits, UploadRules],
                   tuple[np.ndarray, "np.ndarray | None", str, dict[str, Any], "int | None"]]


@dataclass(frozen=True)
class Reply:
    """A generated, validated and encoded mesh and how it was made.

    Attributes
    ----------
    mesh : EncodedMesh
        Its ``stats.fit`` is the fit report of a generated mesh.
    options : dict
        The resolved options, by public name
        (:func:`~spacemesh_service.options.reported_options`).
    model_name, model_version : str
    timings : dict of str to float
    batch_size : int
    sample_scores : list of (int, float)
        ``(seed, fit score)`` of every seed tried (a generated mesh).
    repair : dict, optional
        What a repair did (:func:`~spacemesh_service.outputs.repair_summary`); None for
        a generated mesh.
    input_kind : str, optional
        How a generation's input file was read: ``mesh`` (its surface sampled) or
        ``points`` (``X-SpaceMesh-Input``); None for a repair.
    reduction : dict, optional
        ``{"read": N, "used": M}`` when the upload's N points were reduced to the M the
        pipeline worked on (``X-SpaceMesh-Points-Read`` and ``X-SpaceMesh-Points-Used``,
        ``points_reduced`` in a JSON body); None otherwise.
    """

    mesh: EncodedMesh
    options: dict[str, Any]
    model_name: str
    model_version: str
    timings: dict[str, float]
    batch_size: int
    sample_scores: list[tuple[int, float]] = field(default_factory=list)
    repair: dict[str, Any] | None = None
    input_kind: str | None = None
    reduction: dict[str, int] | None = None

    @property
    def seed(self) -> int:
        """The seed of the mesh (with ``samples > 1``, the winner's)."""
        return int(self.options["seed"])

    @property
    def steps(self) -> int:
        return int(self.options["steps"])

    @property
    def sampler(self) -> str:
        return str(self.options["sampler"])

    def headers(self) -> dict[str, str]:
        """Response headers: ``X-SpaceMesh-*`` statistics and fit report, one per
        resolved option (seed, steps, sampler...), sample scores, and Server-Timing
        (and the repair's statistics)."""
        headers = stats_headers(self.mesh.stats)
        if self.repair is not None:
            headers.update(repair_headers(self.repair))
        headers.update(value_headers(self.options))
        if self.sample_scores:
            headers["X-SpaceMesh-Sample-Scores"] = sample_scores_header(self.sample_scores)
        if self.input_kind is not None:
            headers["X-SpaceMesh-Input"] = self.input_kind
        if self.reduction is not None:
            headers["X-SpaceMesh-Points-Read"] = str(self.reduction["read"])
            headers["X-SpaceMesh-Points-Used"] = str(self.reduction["used"])
        headers.update({
            "X-SpaceMesh-Model": f"{self.model_name}/{self.model_version}",
            "X-SpaceMesh-Batch-Size": str(self.batch_size),
            "Server-Timing": ", ".join(f"{k};dur={v * 1000:.1f}"
                                       for k, v in self.timings.items()),
        })
        return headers


@dataclass(frozen=True)
class MeshUpload:
    """A mesh file as sent: its bytes and name (the extension picks the format)."""

    data: bytes
    filename: str | None


@dataclass(frozen=True)
class _RepairJob:
    """A decoded repair request, its region cut and planned."""

    mesh: PolygonMesh
    region: Region
    plan: RepairPlan | AutoPlan
    options: RequestOptions
    estimate: Estimate


def fibonacci_sphere(count: int) -> np.ndarray:
    """``count`` evenly spread points on the unit sphere (the warm-up input)."""
    i = np.arange(count) + 0.5
    z = 1 - 2 * i / count
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


class Engine:
    """Model, lanes and metrics of one server process.

    Parameters
    ----------
    settings : Settings
    generator : MeshGenerator, optional
        An already loaded generator (default: load ``settings.model`` in :meth:`start`).
    """

    def __init__(self, settings: Settings, *, generator: MeshGenerator | None = None) -> None:
        self.settings = settings
        self.metrics = Metrics()
        self.generator = generator
        self.lanes: Lanes | None = None
        self.state = "loading"  # loading -> ready -> draining; or failed
        self.error: str | None = None
        self._inflight = 0  # requests inside generate()
        #: What one upload may declare or hold, and the parses allowed at once.
        self.read_limits = read_limits(settings)
        self.upload_rules = UploadRules.from_settings(settings)
        self.parsing = ParseSlots(settings.max_parallel_parses)
        #: What one request may cost, and how its cost is estimated.
        self.budget = settings.budget
        self.cost_model = DEFAULT_COST_MODEL

    # ------------------------------------------------------------------ lifecycle
    @property
    def ready(self) -> bool:
        """Model loaded, warm-up passed, not draining."""
        return self.state == "ready"

    def readiness(self) -> tuple[bool, str | None]:
        """Whether new work would be taken and done in time, and why not.

        Returns
        -------
        ready : bool
            :attr:`ready`, and no lane's inference worker stuck or saturated
            (:meth:`~spacemesh_service.lanes.Lanes.overload` against the request
            deadline), so that a balancer sends the work elsewhere.
        detail : str or None
            Why not: the model failed to load, or a lane's overload.
        """
        if self.error:
            return False, f"the model failed to load: {self.error}"
        if not self.ready:
            return False, None
        busy = None if self.lanes is None else self.lanes.overload(
            self.settings.request_timeout_s)
        return busy is None, busy

    @property
    def _generator(self) -> MeshGenerator:
        """:attr:`generator`, once given or loaded (everything but :meth:`start` and the
        model facts runs after that)."""
        if self.generator is None:  # pragma: no cover - start() loads it first
            raise RuntimeError("the model is not loaded (Engine.start)")
        return self.generator

    def _lane(self, estimate: Estimate) -> Batcher:
        """The lane of a request estimated at ``estimate`` (:attr:`lanes` exist once
        :meth:`start` made them; requests are admitted after)."""
        if self.lanes is None:  # pragma: no cover - admit() refuses requests before
            raise RuntimeError("the engine is not started (Engine.start)")
        return self.lanes.for_cost(estimate)

    async def start(self) -> None:
        """Load the model (unless given), run the warm-up, start the lanes.

        Raises
        ------
        Exception
            Whatever loading raised (``state`` becomes ``failed``).
        """
        if self.lanes is not None:
            return
        try:
            if self.generator is None:
                self.generator = await asyncio.to_thread(self._load)
            if self.settings.warmup:
                await asyncio.to_thread(self._warm_up)
        except Exception as error:
            self.state, self.error = "failed", f"{type(error).__name__}: {error}"
            raise
        if self.state != "loading":  # drained while loading
            return
        s = self.settings
        self.lanes = Lanes(self._generator.generate_batch, light=s.light_lane,
                           max_batch_size=s.max_batch_size,
                           max_delay_s=s.max_batch_delay_ms / 1000, queue_size=s.queue_size,
                           metrics=self.metrics)
        self.lanes.start()
        self.metrics.model_info.labels(self.model_name, self.model_version).set(1)
        self.state = "ready"
        self.metrics.ready.set(1)
        log.info("model %s/%s ready", self.model_name, self.model_version)

    def _load(self) -> MeshGenerator:
        return MeshGenerator.from_repository(
            self.settings.model, threads=self.settings.network_threads)

    def _warm_up(self) -> None:
        spec = self._generator.spec
        points = fibonacci_sphere(max(spec.n_points, self.settings.min_points))
        normals = points.copy() if spec.normals else None
        options = GenerateOptions(steps=min(self.default_steps, spec.schedule.timesteps))
        started = time.perf_counter()
        self._generator.generate_batch([GenerateRequest(points, normals, options)])
        log.info("warm-up inference took %.2f s", time.perf_counter() - started)

    def begin_drain(self) -> None:
        """Report not ready and refuse new requests (SIGTERM)."""
        if self.state in ("loading", "ready"):
            self.state = "draining"
            self.metrics.ready.set(0)

    async def stop(self, timeout: float) -> bool:
        """Drain: refuse new requests, let those already inside finish (up to
        ``timeout`` s), then stop the lanes.

        Returns
        -------
        bool
            True when every request finished in time.
        """
        self.begin_drain()
        deadline = time.monotonic() + timeout
        while self._inflight and time.monotonic() < deadline:
            await asyncio.sleep(0.02)
        drained = not self._inflight
        if self.lanes is not None:
            drained = await self.lanes.close(max(0.0, deadline - time.monotonic())) and drained
        return drained

    # ------------------------------------------------------------------ model facts
    @property
    def manifest(self) -> dict[str, Any]:
        repo = getattr(self.generator, "repository", None)
        return repo.manifest if repo is not None else {}

    @property
    def model_name(self) -> str:
        return str(self.manifest.get("name") or getattr(self.generator, "name", "spacemesh"))

    @property
    def model_version(self) -> str:
        return str(self.manifest.get("version", 1))

    @property
    def default_steps(self) -> int:
        """Steps of a request that names none."""
        return self.settings.default_steps or self._generator.spec.steps

    @property
    def max_steps(self) -> int:
        return min(self.settings.max_steps, self._generator.spec.schedule.timesteps)

    def metadata(self) -> dict[str, Any]:
        """KServe v2 model metadata, extended with limits, formats, data card and metrics."""
        spec = self._generator.spec
        manifest = self.manifest
        return {
            "name": self.model_name,
            "versions": [self.model_version],
            "platform": "onnxruntime_onnx",
            "ready": self.ready,
            "inputs": [
                {"name": "points", "datatype": "FP64", "shape": [-1, 3]},
                {"name": "normals", "datatype": "FP64", "shape": [-1, 3],
                 "optional": not spec.normals},
            ],
            "outputs": [{"name": "mesh", "datatype": "BYTES", "shape": [1]}],
            "limits": {**self.settings.limits(), "max_steps": self.max_steps,
                       "max_vertices": spec.max_vertices},
            "input_formats": {"upload": list(INPUT_FORMATS), "json": ["points", "normals"],
                              "repair": list(MESH_FORMATS)},
            "output_formats": dict(MEDIA_TYPES),
            "sampler": {"sampler": spec.method, "default_steps": self.default_steps,
                        "timesteps": spec.schedule.timesteps, "start": spec.start,
                        "start_time": spec.start_time},
            "encoder": {"n_points": spec.n_points, "normals": spec.normals},
            "data": manifest.get("data", {}),
            "metrics": manifest.get("metrics", {}),
            "training": manifest.get("training", {}),
            "files": manifest.get("files", {}),
        }

    # ------------------------------------------------------------------ generate
    def require_ready(self) -> None:
        if self.state == "draining":
            raise Problem(P.SHUTTING_DOWN, "the server is draining before it exits",
                          retry_after=1)
        if not self.ready:
            detail = ("the model failed to load: " + self.error) if self.error else (
                "the model is loading")
            raise Problem(P.NOT_READY, detail, retry_after=1)

    def _decode(self, parse: ParseFn, options: dict[str, Any]
                ) -> tuple[Any, RequestOptions, Estimate]:
        points, normals, source, body_options, points_read = parse(
            self.read_limits, self.upload_rules)
        merged = {**{k: v for k, v in options.items() if v is not None}, **body_options}
        opts = resolve_request(merged, GENERATE_ROUTE_OPTIONS, self._generator.spec,
                               self.settings)
        cloud = validate_cloud(points, normals, self.settings, source=source,
                               needs_normals=self._generator.spec.normals,
                               points_read=points_read)
        estimate = self.cost_model.generate(self._generator.spec, opts.resolved,
                                            len(cloud.points))
        self._within_budget(estimate, "generate")
        return cloud, opts, estimate

    def _within_budget(self, estimate: Estimate, route: str) -> None:
        """Refuse a request whose estimated cost is over :attr:`budget` (422
        ``too-expensive``, counted by route and the option it names)."""
        try:
            self.budget.check(estimate, what=route)
        except CostError as error:
            self.metrics.too_expensive.labels(route, error.option or "none").inc()
            raise P.cost_problem(error) from None

    async def generate(self, parse: ParseFn, options: dict[str, Any], *,
                       progress: ProgressFn | None = None,
                       stage: StageFn | None = None) -> Reply:
        """Generate one mesh.

        Parameters
        ----------
        parse : callable
            Reads the request body (in a worker thread); may raise :class:`Problem`.
        options : dict
            Option values by name from the query string, form or gRPC message (None: not
            given); options in a JSON body (returned by ``parse``) take precedence.
            Resolved once (:func:`~spacemesh_service.options.resolve_request`): a name
            not in :data:`~spacemesh_service.options.GENERATE_ROUTE_OPTIONS` or a value
            not of its type is a 422 ``invalid-option``.
        progress : callable, optional
            ``progress(done, total)`` after each sampler step (on the event loop).
        stage : callable, optional
            ``stage(name, done, total)`` as each stage begins (on the event loop):
            ``queued``, the pipeline's stages, then ``encode_output``.

        Returns
        -------
        Reply

        Raises
        ------
        Problem
        RuntimeError
            Called outside :meth:`admit`.
        """
        if not self._inflight:
            raise RuntimeError("call Engine.generate inside 'with engine.admit():'")
        return await self._generate(parse, options, progress, stage)

    @contextlib.contextmanager
    def admit(self) -> Iterator[None]:
        """Admit one request (503 when not ready or draining); a drain waits for it.

        Both servers wrap everything a generate request does, from reading its body to
        sending its mesh, in this context.
        """
        self.require_ready()
        self._inflight += 1
        self.metrics.inflight.inc()
        try:
            yield
        finally:
            self._inflight -= 1
            self.metrics.inflight.dec()

    async def _generate(self, parse: ParseFn, options: dict[str, Any],
                        progress: ProgressFn | None, stage: StageFn | None = None) -> Reply:
        started = time.perf_counter()
        cloud, opts, estimate = await self.parsing.run(self._decode, parse, options)
        decode_s = time.perf_counter() - started
        self.metrics.observe_stage("decode_input", decode_s)
        request = GenerateRequest(cloud.points, cloud.normals, opts.resolved)
        lane = self._lane(estimate)
        outcome = await self._queued(
            lane.submit(request, key=opts.batch_key, progress=progress, stage=stage),
            decode_s, lane)
        result = outcome.result
        self.metrics.observe_stage("queue", outcome.queue_seconds)
        self.metrics.observe_stage("extraction", result.timings.get("extraction", 0.0))
        options = reported_options(result.options)
        scores = [(int(seed), float(score)) for seed, score in result.sample_scores]
        info = {**options, "model": {"name": self.model_name, "version": self.model_version},
                "sample_scores": [{"seed": seed, "score": finite_or_none(score)}
                                  for seed, score in scores]}
        if cloud.reduction is not None:
            info["points_reduced"] = cloud.reduction
        fit = result.fit.to_dict() if result.fit is not None else None
        timings = {"decode_input": decode_s, "queue": outcome.queue_seconds}
        timings.update({k: v for k, v in result.timings.items() if k != "total"})
        if stage is not None:
            stage("encode_output", 1, 1)
        t0 = time.perf_counter()
        try:
            encoded = await self._encoded(started, result.mesh, opts.format, info, fit)
        except Problem as problem:  # no-surface: say how, so it can be replayed
            problem.extra.update(options=options, seed=result.seed, steps=result.steps,
                                 timings=timings)
            raise
        timings["encode_output"] = time.perf_counter() - t0
        timings["total"] = time.perf_counter() - started
        self.metrics.observe_stage("encode_output", timings["encode_output"])
        return Reply(encoded, options, self.model_name, self.model_version, timings,
                     outcome.batch_size, sample_scores=scores, input_kind=cloud.input_kind,
                     reduction=cloud.reduction)

    async def _encoded(self, started: float, mesh: PolygonMesh, fmt: str,
                       info: dict[str, Any], fit: dict[str, Any] | None = None
                       ) -> EncodedMesh:
        """:func:`~spacemesh_service.outputs.encode_mesh` in a worker thread, within what
        is left of the request's deadline (counted from ``started``, a
        :func:`time.perf_counter`): past it the answer is 504 ``timeout`` and the encoding
        stops at its next checkpoint (:mod:`spacemesh.cancel`; between validating and
        writing), as it does when the client leaves."""
        remaining = self.settings.request_timeout_s - (time.perf_counter() - started)
        if remaining <= 0:
            raise self._timeout()
        end = time.monotonic() + remaining
        gone = threading.Event()  # the client left, or the deadline passed

        def run() -> EncodedMesh:
            with cancel_scope(lambda: gone.is_set() or time.monotonic() > end):
                return encode_mesh(mesh, fmt, info, fit)

        try:
            return await asyncio.wait_for(asyncio.to_thread(run), remaining)
        except (asyncio.TimeoutError, Cancelled):
            gone.set()
            raise self._timeout() from None
        except asyncio.CancelledError:
            gone.set()
            raise

    def _timeout(self) -> Problem:
        """504 ``timeout``: the request deadline passed."""
        return Problem(P.TIMEOUT, f"no result within {self.settings.request_timeout_s} s; "
                       "the work was cancelled", timeout_s=self.settings.request_timeout_s)

    async def _queued(self, work: Any, spent: float, lane: Batcher) -> Any:
        """Await ``lane`` (its ``submit`` or ``submit_call``) within what is left of the
        request timeout; its exceptions become problems."""
        remaining = self.settings.request_timeout_s - spent
        try:
            if remaining <= 0:
                work.close()
                raise asyncio.TimeoutError
            return await asyncio.wait_for(work, remaining)
        except asyncio.TimeoutError:
            raise self._timeout() from None
        except QueueFull:
            raise Problem(P.QUEUE_FULL, f"{lane.depth} requests are waiting already",
                          retry_after=lane.retry_after()) from None
        except ShuttingDown:
            raise Problem(P.SHUTTING_DOWN, "the server is draining before it exits",
                          retry_after=1) from None
        except RegionError as error:  # pragma: no cover - planned before queueing
            raise P.region_problem(error) from None
        except OptionError as error:  # pragma: no cover - resolved before queueing
            raise option_problem(error) from None
        except ValueError as error:  # the pipeline's own input checks
            raise Problem(P.INVALID_PARAMETER, str(error)) from None

    # ------------------------------------------------------------------ repair
    def _decode_repair(self, upload: MeshUpload, region: Any,
                       options: dict[str, Any]) -> _RepairJob:
        opts = resolve_request(options, REPAIR_ROUTE_OPTIONS, self._generator.spec,
                               self.settings)
        shape = read_region(region, self.read_limits)
        mesh, _ = read_mesh_upload(upload.data, upload.filename, self.read_limits,
                                   self.upload_rules)
        try:
            plan = plan_repair(mesh, shape, self._generator.spec.max_vertices,
                               weld=opts.weld, max_growth=opts.max_growth)
        except RegionError as error:
            raise P.region_problem(error) from None
        steps = int(opts.resolved.steps or self.default_steps)
        spec = self._generator.spec
        if isinstance(plan, AutoPlan):
            estimate = self.cost_model.repair(
                spec, steps=steps, faces=plan.mesh.n_faces, passes=plan.model_passes,
                fills=plan.fills, fill_vertices2=plan.fill_vertices2, automatic=True)
        else:
            estimate = self.cost_model.repair(spec, steps=steps, faces=plan.cut.mesh.n_faces)
        self._within_budget(estimate, "repair")
        return _RepairJob(mesh, shape, plan, opts, estimate)

    async def repair(self, upload: MeshUpload, region: Any, options: dict[str, Any], *,
                     progress: ProgressFn | None = None,
                     stage: StageFn | None = None) -> Reply:
        """Re-generate a region of a mesh (:func:`spacemesh.repair.repair_mesh`).

        The mesh and region are read, and the region cut and planned, in a worker
        thread, so every region error answers 422 before the request is queued; the
        planning runs in a cancellation scope (:mod:`spacemesh.cancel`), so the request's
        deadline (504) or a client that leaves stops it at its next checkpoint. The
        repair then waits in the queue of its lane and runs alone in its inference thread.

        Parameters
        ----------
        upload : MeshUpload
            The mesh file.
        region : str, bytes or dict
            The region's JSON text (REST) or JSON form (gRPC).
        options : dict
            Option values by name: those of
            :data:`~spacemesh_service.options.REPAIR_ROUTE_OPTIONS`, ``format``,
            ``seed``, ``steps``, ``sampler``, ``weld``, ``max_growth`` (None: not given;
            any other name is a 422 ``invalid-option``).
            With ``weld``
            the mesh's vertices at equal positions are merged before the cut (the
            region's vertex indices are the file's), and the output is the welded mesh
            repaired.
        progress : callable, optional
            ``progress(done, total)`` after each sampler step (on the event loop).
        stage : callable, optional
            ``stage(name, done, total)`` (on the event loop): ``queued``, then
            ``encode_output``.

        Returns
        -------
        Reply
            With :attr:`Reply.repair`; ``batch_size`` is 1.

        Raises
        ------
        Problem
        RuntimeError
            Called outside :meth:`admit`.
        """
        if not self._inflight:
            raise RuntimeError("call Engine.repair inside 'with engine.admit():'")
        started = time.perf_counter()
        deadline = time.monotonic() + self.settings.request_timeout_s
        gone = threading.Event()  # the client left: the planning stops

        def plan() -> _RepairJob:  # in a parse thread: planning a big automatic region
            with cancel_scope(lambda: gone.is_set() or time.monotonic() > deadline):
                return self._decode_repair(upload, region, options)

        try:
            job = await self.parsing.run(plan)
        except asyncio.CancelledError:
            gone.set()
            raise
        except Cancelled:  # the deadline passed while the region was planned
            raise self._timeout() from None
        except Problem as problem:
            if problem.kind in P.REGION_KINDS:
                self.metrics.repair_rejected.labels(problem.kind.slug).inc()
            raise
        decode_s = time.perf_counter() - started
        self.metrics.observe_repair_stage("decode_input", decode_s - job.plan.seconds)
        opts = job.options
        chosen = opts.resolved

        def run(report: ProgressFn) -> Any:  # in the inference thread
            return repair_mesh(job.mesh, job.region, self.generator, seed=chosen.seed,
                               steps=chosen.steps, method=chosen.sampler, progress=report,
                               plan=job.plan, weld=opts.weld)

        lane = self._lane(job.estimate)
        outcome = await self._queued(
            lane.submit_call(run, progress=progress, stage=stage), decode_s, lane)
        result = outcome.result
        issues = verify_repair(job.plan, result)
        if issues:  # a faulty repair is refused, never returned
            log.error("repair refused: %s", "; ".join(issues))
            raise Problem(P.INVALID_OUTPUT, "the repair changed the mesh outside the grown "
                          "region: " + "; ".join(issues))
        stats = result.stats
        summary = repair_summary(stats)
        options = {"seed": stats.seed, "steps": stats.steps, "sampler": stats.method}
        info = {**options, "model": {"name": self.model_name, "version": self.model_version},
                "repair": summary}
        timings = {"decode_input": decode_s - job.plan.seconds, "queue": outcome.queue_seconds}
        timings.update({k: v for k, v in stats.timings.items() if k != "total"})
        if stage is not None:
            stage("encode_output", 1, 1)
        t0 = time.perf_counter()
        encoded = await self._encoded(started, result.mesh, opts.format, info)
        timings["encode_output"] = time.perf_counter() - t0
        timings["total"] = time.perf_counter() - started
        m = self.metrics
        for stage_name in ("queue", "cut", "patch", "encoder", "sampler", "connectivity",
                           "splice", "encode_output"):
            if stage_name in timings:
                m.observe_repair_stage(stage_name, timings[stage_name])
        m.repairs.labels(stats.fallback).inc()
        m.repair_region_faces.observe(stats.region_faces)
        return Reply(encoded, options, self.model_name, self.model_version, timings,
                     outcome.batch_size, repair=summary)
