"""Dynamic batching: concurrent requests share one onnxruntime batch.

Requests wait in a bounded queue. One worker task takes the oldest, waits up to
``max_delay_s`` for more requests with the same batch key (the resolved sampler settings:
steps, sampler, start and start time), up to ``max_batch_size``, and runs them as one
:meth:`MeshGenerator.generate_batch` call in
a dedicated inference thread (so the event loop never runs inference, and one batch runs
at a time). Each request keeps its own seed, so batching never changes a mesh.

A full queue raises :class:`QueueFull`. A caller that is cancelled (its timeout, or a
client that went away) leaves the queue; when every request of a running batch has
been cancelled the batch stops at the next sampler step.

:meth:`Batcher.submit_call` queues work that does not batch (a repair): it waits in the
same queue, counts against the same ``queue_size`` and runs alone in the same inference
thread, so generation and repair never compete for the cores.

The service runs two batchers, the lanes of :class:`spacemesh_service.lanes.Lanes`; each
is named by its ``lane`` in the metrics.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
import time
from collections.abc import Callable, Hashable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from spacemesh.cancel import Cancelled, cancel_scope
from spacemesh.runtime.request import GenerateRequest, GenerateResult
from spacemesh.runtime.sampler import StageFn
from spacemesh_service.metrics import BATCH_STAGES, Metrics

log = logging.getLogger("spacemesh.service")

#: ``progress(done, total)``.
ProgressFn = Callable[[int, int], None]
#: ``run(requests, progress[, stage]) -> results``: :meth:`MeshGenerator.generate_batch`
#: (given ``stage=`` only when a request of the batch asked for stages).
RunBatch = Callable[..., list[GenerateResult]]
#: ``call(progress) -> result``: work run alone (:meth:`Batcher.submit_call`).
SoloCall = Callable[[ProgressFn], Any]


class QueueFull(Exception):
    """The queue holds ``queue_size`` requests already."""


class ShuttingDown(Exception):
    """The batcher no longer accepts requests."""


class _AllCancelled(Cancelled):
    """Raised inside the inference thread to stop a batch nobody waits for (at a sampler
    step or a stage event; :func:`spacemesh.cancel.checkpoint` raises its base class
    inside long stages)."""


@dataclass(frozen=True)
class Outcome:
    """What a request gets back.

    Attributes
    ----------
    result : GenerateResult
        Or what the call of :meth:`Batcher.submit_call` returned.
    batch_size : int
        Requests in the batch it ran in (1 for a call).
    queue_seconds : float
        Time between submission and the start of its batch.
    """

    result: Any
    batch_size: int
    queue_seconds: float


def sampler_key(request: GenerateRequest) -> Hashable:
    """The default batch key: the sampler settings of the request's options."""
    o = request.options
    return (o.steps, o.sampler, o.start, o.start_time)


@dataclass(eq=False)
class _Job:
    request: GenerateRequest | None
    future: asyncio.Future
    progress: ProgressFn | None
    call: SoloCall | None = None
    batch_key: Hashable = None
    stage: StageFn | None = None
    enqueued: float = field(default_factory=time.perf_counter)
    queue_seconds: float = 0.0
    cancelled: bool = False

    @property
    def key(self) -> Hashable:
        if self.request is None:  # a call: batches with nothing
            return ("call", id(self))
        return self.batch_key


class Batcher:
    """An asyncio dynamic batcher in front of one generator.

    Parameters
    ----------
    run : callable
        ``run(requests, progress=fn) -> results`` (``MeshGenerator.generate_batch``).
    max_batch_size : int
    max_delay_s : float
        How long the first request of a batch waits for others.
    queue_size : int
        Most requests waiting (not counting the running batch).
    metrics : Metrics, optional
    lane : str
        The lane's name in the metrics (``spacemesh_lane_*{lane}``) and the name of its
        inference thread.
    """

    def __init__(self, run: RunBatch, *, max_batch_size: int, max_delay_s: float,
                 queue_size: int, metrics: Metrics | None = None,
                 lane: str = "main") -> None:
        self._run_batch = run
        self.lane = lane
        self.max_batch_size = max_batch_size
        self.max_delay_s = max_delay_s
        self.queue_size = queue_size
        self.metrics = metrics
        self._pending: collections.deque[_Job] = collections.deque()
        self._open: set[_Job] = set()  # submitted and not yet answered
        self._arrived = asyncio.Event()
        self._closing = False
        self._worker: asyncio.Task | None = None
        self._executor = ThreadPoolExecutor(1, thread_name_prefix=f"spacemesh-{lane}")
        self._batch_seconds = 0.0  # moving average, for Retry-After
        self._running_since: float | None = None  # monotonic start of the running batch

    # ------------------------------------------------------------------ public
    def start(self) -> None:
        """Start the worker task (call from the event loop)."""
        if self._worker is None:
            self._worker = asyncio.get_running_loop().create_task(self._work(),
                                                                   name="spacemesh-batcher")

    @property
    def depth(self) -> int:
        """Requests waiting for a batch."""
        return len(self._pending)

    @property
    def busy(self) -> bool:
        """Whether any request waits, is being batched, or runs."""
        return bool(self._open)

    def overload(self, deadline_s: float) -> str | None:
        """Why new work would not be done within ``deadline_s`` seconds (None: it would).

        The running batch has run for longer than the deadline (stuck, or one heavy
        request), the queue is full, or the queue's expected time (its batches at the
        average batch time) is longer than the deadline.

        Parameters
        ----------
        deadline_s : float
            A request's deadline.

        Returns
        -------
        str or None
            The reason, for readiness's ``detail``.
        """
        if self._running_since is not None:
            running = time.monotonic() - self._running_since
            if running > deadline_s:
                return (f"the running batch has taken {running:.0f} s, longer than the "
                        f"{deadline_s:g} s deadline")
        if self.depth >= self.queue_size:
            return f"the queue is full ({self.depth} requests wait)"
        waiting = (self.depth / self.max_batch_size + 1) * self._batch_seconds
        if self.depth and waiting > deadline_s:
            return (f"the {self.depth} waiting requests would take about {waiting:.0f} s, "
                    f"longer than the {deadline_s:g} s deadline")
        return None

    def retry_after(self) -> int:
        """Seconds a rejected client should wait: the expected time to drain the queue."""
        batches = self.depth / self.max_batch_size + 1
        return max(1, int(batches * self._batch_seconds + 0.999))

    async def submit(self, request: GenerateRequest, *, key: Hashable = None,
                     progress: ProgressFn | None = None,
                     stage: StageFn | None = None) -> Outcome:
        """Queue a request and wait for its result.

        Parameters
        ----------
        request : GenerateRequest
            Passed to the generator unchanged.
        key : hashable, optional
            Requests batch only with requests of the same key (the engine gives the
            resolved sampler settings); default :func:`sampler_key`.
        progress : callable, optional
            ``progress(done, total)``, called on the event loop after each sampler step.
        stage : callable, optional
            ``stage(name, done, total)``, called on the event loop: ``queued``
            (``done``-th of ``total`` waiting) once accepted, then as each stage of the
            pipeline begins (:meth:`MeshGenerator.generate_batch`).

        Returns
        -------
        Outcome

        Raises
        ------
        QueueFull, ShuttingDown
        """
        return await self._enqueue(request, None, progress,
                                   sampler_key(request) if key is None else key, stage)

    async def submit_call(self, call: SoloCall, *, progress: ProgressFn | None = None,
                          stage: StageFn | None = None) -> Outcome:
        """Queue work that runs alone in the inference thread, and wait for its result.

        Parameters
        ----------
        call : callable
            ``call(progress) -> result``; ``progress(done, total)`` must be called after
            each sampler step (it raises when the caller has given up, which stops the
            work).
        progress : callable, optional
            ``progress(done, total)``, called on the event loop.
        stage : callable, optional
            ``stage("queued", done, total)`` once accepted (the call reports no stages).

        Returns
        -------
        Outcome
            ``result`` is what ``call`` returned, ``batch_size`` 1.

        Raises
        ------
        QueueFull, ShuttingDown
            And whatever ``call`` raised.
        """
        return await self._enqueue(None, call, progress, None, stage)

    async def _enqueue(self, request: GenerateRequest | None, call: SoloCall | None,
                       progress: ProgressFn | None, key: Hashable = None,
                       stage: StageFn | None = None) -> Outcome:
        if self._closing:
            raise ShuttingDown
        if len(self._pending) >= self.queue_size:
            raise QueueFull
        job = _Job(request, asyncio.get_running_loop().create_future(), progress, call, key,
                   stage)
        self._open.add(job)
        job.future.add_done_callback(lambda _: self._open.discard(job))
        self._pending.append(job)
        self._set_depth()
        self._arrived.set()
        if stage is not None:
            stage("queued", len(self._pending), self.queue_size)
        try:
            return await job.future
        except asyncio.CancelledError:
            job.cancelled = True
            if self.metrics is not None:
                self.metrics.cancelled.inc()
            with contextlib.suppress(ValueError):
                self._pending.remove(job)
            self._set_depth()
            raise

    async def close(self, timeout: float) -> bool:
        """Stop accepting requests, let waiting and running ones finish, stop the worker.

        Requests still open after ``timeout`` fail with :class:`ShuttingDown`.

        Parameters
        ----------
        timeout : float
            Seconds to wait for the queue to empty.

        Returns
        -------
        bool
            True when every request finished in time.
        """
        self._closing = True
        deadline = time.monotonic() + timeout
        while self.busy and time.monotonic() < deadline:
            await asyncio.sleep(0.02)
        drained = not self.busy
        for job in list(self._open):
            job.cancelled = True
            self._settle(job, error=ShuttingDown())
        if self._worker is not None:
            self._worker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._worker
        self._executor.shutdown(wait=False, cancel_futures=True)
        return drained

    # ------------------------------------------------------------------ worker
    def _set_depth(self) -> None:
        if self.metrics is not None:
            self.metrics.set_queue_depth(self.lane, len(self._pending))

    def _set_running(self, count: int) -> None:
        if self.metrics is not None:
            self.metrics.lane_running.labels(self.lane).set(count)

    def _pop_first(self) -> _Job | None:
        while self._pending:
            job = self._pending.popleft()
            if not job.cancelled and not job.future.done():
                return job
        return None

    def _take_compatible(self, batch: list[_Job]) -> None:
        key = batch[0].key
        for job in list(self._pending):
            if len(batch) >= self.max_batch_size:
                break
            if job.key == key and not job.cancelled:
                self._pending.remove(job)
                batch.append(job)
        self._set_depth()

    async def _collect(self) -> list[_Job]:
        while True:
            while not self._pending:
                self._arrived.clear()
                await self._arrived.wait()
            first = self._pop_first()
            if first is not None:
                break
        batch = [first]
        if first.call is not None:  # runs alone: nothing to wait for
            self._set_depth()
            return batch
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.max_delay_s
        while True:
            self._take_compatible(batch)
            remaining = deadline - loop.time()
            if len(batch) >= self.max_batch_size or remaining <= 0:
                break
            self._arrived.clear()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._arrived.wait(), remaining)
        self._set_depth()
        return batch

    async def _work(self) -> None:
        while True:
            batch = await self._collect()
            self._running_since = time.monotonic()
            self._set_running(len(batch))
            try:
                await self._run(batch)
            except Exception:  # pragma: no cover - _run settles every future
                log.exception("batch failed")
            finally:
                self._running_since = None
                self._set_running(0)

    def _record_duration(self, elapsed: float) -> None:
        self._batch_seconds = elapsed if not self._batch_seconds else (
            0.8 * self._batch_seconds + 0.2 * elapsed)

    async def _run_call(self, job: _Job, call: SoloCall) -> None:
        loop = asyncio.get_running_loop()
        start = time.perf_counter()
        job.queue_seconds = start - job.enqueued

        def progress(done: int, total: int) -> None:  # in the inference thread
            if job.cancelled:
                raise _AllCancelled
            if job.progress is not None:
                loop.call_soon_threadsafe(job.progress, done, total)

        def run() -> Any:  # in the inference thread
            with cancel_scope(lambda: job.cancelled):
                return call(progress)

        try:
            result = await loop.run_in_executor(self._executor, run)
        except Cancelled:
            log.info("stopped a cancelled call")
            if self.metrics is not None:
                self.metrics.stopped_batches.inc()
            return
        except Exception as error:
            self._settle(job, error=error)
            return
        self._record_duration(time.perf_counter() - start)
        self._settle(job, Outcome(result, 1, job.queue_seconds))

    async def _run(self, batch: list[_Job]) -> None:
        call = batch[0].call
        if call is not None:  # alone by its key
            await self._run_call(batch[0], call)
            return
        log.debug("running a batch of %d", len(batch))
        loop = asyncio.get_running_loop()
        start = time.perf_counter()
        for job in batch:
            job.queue_seconds = start - job.enqueued
        if self.metrics is not None:
            self.metrics.batch_size.observe(len(batch))
            self.metrics.batches.inc()

        def abandoned() -> bool:
            return all(job.cancelled for job in batch)

        def progress(done: int, total: int) -> None:  # in the inference thread
            if abandoned():
                raise _AllCancelled
            for job in batch:
                if job.progress is not None and not job.cancelled:
                    loop.call_soon_threadsafe(job.progress, done, total)

        def stage(name: str, done: int, total: int) -> None:  # in the inference thread
            # every stage boundary is a place to stop: decode, geometry, report, more
            # seeds, untangling and tolerance tries, not only the sampler's steps
            if abandoned():
                raise _AllCancelled
            for job in batch:
                if job.stage is not None and not job.cancelled:
                    loop.call_soon_threadsafe(job.stage, name, done, total)

        try:
            requests = [j.request for j in batch if j.request is not None]  # no call here
            results = await self._call(loop, requests, progress, stage, abandoned)
        except Cancelled:
            log.info("stopped a batch of %d cancelled requests", len(batch))
            if self.metrics is not None:
                self.metrics.stopped_batches.inc()
            return
        except Exception as error:
            if len(batch) > 1:  # find the request that fails; the others still succeed
                for job in batch:
                    if not job.cancelled:
                        await self._run([job])
                return
            self._settle(batch[0], error=error)
            return
        self._record_duration(time.perf_counter() - start)
        if self.metrics is not None and results:
            for stage_name in BATCH_STAGES:
                if stage_name in results[0].timings:
                    self.metrics.observe_stage(stage_name, results[0].timings[stage_name])
        for job, result in zip(batch, results, strict=True):
            self._settle(job, Outcome(result, len(batch), job.queue_seconds))

    async def _call(self, loop: asyncio.AbstractEventLoop, requests: Sequence[GenerateRequest],
                    progress: ProgressFn, stage: StageFn, is_cancelled: Callable[[], bool]
                    ) -> list[GenerateResult]:
        def run() -> list[GenerateResult]:  # in the inference thread
            with cancel_scope(is_cancelled):
                return self._run_batch(list(requests), progress=progress, stage=stage)

        return await loop.run_in_executor(self._executor, run)

    @staticmethod
    def _settle(job: _Job, outcome: Outcome | None = None,
                error: BaseException | None = None) -> None:
        if job.future.done():
            return
        if error is not None:
            job.future.set_exception(error)
        else:
            job.future.set_result(outcome)
