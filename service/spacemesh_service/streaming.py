"""Progress over REST: ``POST /generate/stream`` and ``POST /repair/stream`` as
Server-Sent Events (``text/event-stream``).

A streaming request is the same request as ``/generate`` or ``/repair`` (same body, same
options, same engine, queue, batching and timeout). It answers with events:

``progress``
    ``{"stage", "done", "total", "fraction"}``, one per stage of the work as it begins
    and one per sampler step: ``queued`` (``done``-th waiting of at most ``total``),
    ``encoder``, ``sampler`` (then one event per diffusion step, ``done`` of ``total``),
    ``connectivity``, ``decode``, ``geometry``, ``report`` (``done``-th of ``total``
    meshes, several with ``samples``), ``encode_output``. A repair reports ``queued``, its
    sampler steps and ``encode_output``. ``fraction`` in [0, 1] is a rough share of the
    work done, never decreasing (for a progress bar).
``result``
    ``{"format", "media_type", "filename", "headers", "body"}``: the mesh of the plain
    route, ``body`` base64 of exactly the bytes it would have answered, ``headers`` its
    response headers (``X-SpaceMesh-*`` statistics and fit report, ``Server-Timing``...).
``problem``
    An ``application/problem+json`` body (with its ``status``): an error after the stream
    has started (a queue timeout, no surface, ...). Nothing follows it.

An error before the stream starts (a bad body or option, a full queue, not ready)
is a plain problem+json response with its status: the stream starts only once the
request is decoded and queued. While it waits, a comment line is sent every
:data:`KEEPALIVE_S` seconds so proxies keep the connection. A client that goes away
cancels the request as for the plain routes.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import logging
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

from fastapi import Request
from fastapi.responses import StreamingResponse

from spacemesh_service import problems as P
from spacemesh_service.engine import Engine, Reply
from spacemesh_service.problems import Problem

log = logging.getLogger("spacemesh.service")

#: Media type of the streaming routes.
EVENT_STREAM = "text/event-stream"
#: Seconds between keep-alive comments while nothing happens.
KEEPALIVE_S = 15.0

#: Where each stage begins on the progress bar (the sampler's steps fill its span).
_STAGE_FRACTIONS = {"queued": 0.02, "encoder": 0.05, "sampler": 0.1, "connectivity": 0.6,
                    "decode": 0.65, "geometry": 0.7, "report": 0.9, "encode_output": 0.95}
#: Stages reported per mesh (their span is shared by the ``total`` meshes).
_PER_MESH = {"decode": "geometry", "geometry": "report", "report": "encode_output"}

#: ``work(progress, stage) -> Reply``: the engine call of one request.
Work = Callable[[Callable[[int, int], None], Callable[[str, int, int], None]], Awaitable[Reply]]


def sse(event: str, data: dict[str, Any]) -> bytes:
    """One Server-Sent Event: ``event: <name>`` and its JSON ``data`` line."""
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n".encode()


class ProgressEvents:
    """Collects a request's stage and step reports (on the event loop) as events."""

    def __init__(self) -> None:
        self.queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        self._fraction = 0.0

    def _fraction_of(self, name: str, done: int, total: int) -> float:
        start = _STAGE_FRACTIONS.get(name, self._fraction)
        if name == "sampler_step":
            start, end = _STAGE_FRACTIONS["sampler"], _STAGE_FRACTIONS["connectivity"]
            return start + (end - start) * done / max(total, 1)
        if name in _PER_MESH and total > 1:
            end = _STAGE_FRACTIONS[_PER_MESH[name]]
            return start + (end - start) * (done - 1) / total
        return start

    def stage(self, name: str, done: int, total: int) -> None:
        """``stage(name, done, total)``: a stage begins."""
        self._fraction = max(self._fraction, self._fraction_of(name, done, total))
        self.queue.put_nowait({"stage": name, "done": int(done), "total": int(total),
                               "fraction": round(self._fraction, 4)})

    def step(self, done: int, total: int) -> None:
        """``progress(done, total)``: a sampler step finished."""
        self._fraction = max(self._fraction, self._fraction_of("sampler_step", done, total))
        self.queue.put_nowait({"stage": "sampler", "done": int(done), "total": int(total),
                               "fraction": round(self._fraction, 4)})


def result_event(reply: Reply, filename: str) -> dict[str, Any]:
    """The ``result`` event of a reply: its mesh (base64) and the plain route's headers."""
    return {"format": reply.mesh.format, "media_type": reply.mesh.media_type,
            "filename": filename, "headers": reply.headers(),
            "body": base64.b64encode(reply.mesh.body).decode("ascii")}


async def next_event(events: ProgressEvents, task: asyncio.Future,
                      timeout: float | None = None) -> dict[str, Any] | None:
    """The next progress event, or None once ``task`` is done and no event is left
    (or nothing came within ``timeout``: then ``{}``)."""
    if not events.queue.empty():
        return events.queue.get_nowait()
    if task.done():
        return None
    getter = asyncio.ensure_future(events.queue.get())
    try:
        await asyncio.wait({getter, task}, timeout=timeout,
                           return_when=asyncio.FIRST_COMPLETED)
    finally:
        if not getter.done():
            getter.cancel()
    if getter.done() and not getter.cancelled():
        return getter.result()
    if not events.queue.empty():
        return events.queue.get_nowait()
    return None if task.done() else {}


def _problem_of(error: BaseException, path: str) -> dict[str, Any]:
    if not isinstance(error, Problem):
        log.error("unhandled error in a stream on %s", path,
                  exc_info=(type(error), error, error.__traceback__))
        error = Problem(P.INTERNAL, "an unexpected error occurred")
    return error.to_dict(path)


async def stream_response(request: Request, engine: Engine, work: Work,
                          filename: Callable[[Reply], str]) -> StreamingResponse:
    """Run ``work`` for a request and answer with its events.

    The request is admitted (:meth:`Engine.admit`) until its stream ends. This returns
    once the first event has come (the request was decoded and queued); an error
    before that is raised, so it becomes a plain problem+json response.

    Parameters
    ----------
    request : Request
    engine : Engine
    work : callable
        ``work(progress, stage) -> Reply``: reads the body and calls
        :meth:`Engine.generate` or :meth:`Engine.repair` with the two reporters.
    filename : callable
        The mesh's file name from its reply (as in the plain route's
        ``Content-Disposition``).

    Returns
    -------
    StreamingResponse

    Raises
    ------
    Problem
        Anything that went wrong before the first event.
    """
    stack = contextlib.ExitStack()
    stack.enter_context(engine.admit())
    events = ProgressEvents()
    task = asyncio.ensure_future(work(events.step, events.stage))
    try:
        first = await next_event(events, task)
        if first is None:  # finished (or failed) before any event
            task.result()
    except BaseException:
        task.cancel()
        stack.close()
        raise
    path = request.url.path

    async def body() -> AsyncIterator[bytes]:
        try:
            event = first
            while event is not None:
                yield sse("progress", event) if event else b": keep-alive\n\n"
                event = await next_event(events, task, KEEPALIVE_S)
            try:
                reply = task.result()
            except Exception as error:
                yield sse("problem", _problem_of(error, path))
                return
            yield sse("result", result_event(reply, filename(reply)))
        finally:  # also when the client went away (the stream is cancelled)
            if not task.done():
                task.cancel()
                log.info("client went away; cancelled its %s request", path)
                with contextlib.suppress(BaseException):
                    await task
            stack.close()

    return StreamingResponse(body(), media_type=EVENT_STREAM,
                             headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})


def stream_responses(plain: dict[int | str, dict[str, Any]]) -> dict[int | str, dict[str, Any]]:
    """The OpenAPI responses of a streaming route: the plain route's errors (before the
    stream starts) and a 200 ``text/event-stream``."""
    events = ("Server-Sent Events: `progress` (JSON `{stage, done, total, fraction}`) "
              "while it runs, then one `result` (JSON `{format, media_type, filename, "
              "headers, body}`, `body` the mesh's bytes in base64, `headers` those of the "
              "plain route) or one `problem` (a problem+json body).")
    return {**{k: v for k, v in plain.items() if k != 200},
            200: {"description": events, "content": {EVENT_STREAM: {
                "example": 'event: progress\ndata: {"stage":"queued","done":1,"total":32,'
                           '"fraction":0.02}\n\nevent: result\ndata: {"format":"glb",...}\n\n'}}}}
