"""The gRPC server's interceptor: API keys, rate limits, request ids and access logs.

The gRPC counterpart of :class:`spacemesh_service.security.RestGuard` and
:class:`spacemesh_service.access_log.RestAccessLog`. Every call's handler is wrapped:

* the caller (peer address, ``x-forwarded-for`` from a trusted proxy, ``authorization:
  Bearer KEY`` metadata) is checked by the shared :class:`~spacemesh_service.security.Guard`
  before the handler runs; a refused call ends as UNAUTHENTICATED or RESOURCE_EXHAUSTED
  with the same problem metadata as every other error (``problem-type``,
  ``problem-status``, ``retry-after``), and is counted in the metrics;
* the request id (``x-request-id`` metadata when sane, else a new one) is sent back in the
  trailing metadata, whatever the outcome;
* one access line is logged when the call ends.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any

import grpc

from spacemesh_service.access_log import log_request, request_id
from spacemesh_service.problems import Problem
from spacemesh_service.security import Guard, grpc_peer_address

Metrics = Any  # spacemesh_service.metrics.Metrics


async def abort_with(context: grpc.aio.ServicerContext, problem: Problem) -> None:
    """End a call with a problem: its status code and detail, and its metadata added to
    the trailing metadata already set (the request id).

    Raises
    ------
    grpc.aio.AbortError
        Always (as ``context.abort``).
    """
    kept = tuple(context.trailing_metadata() or ())
    await context.abort(problem.kind.grpc_code, problem.detail,
                        trailing_metadata=(*kept, *problem.grpc_metadata()))


class _Call:
    """One call as the interceptor sees it."""

    def __init__(self, guard: Guard, metrics: Metrics | None, method: str,
                 metadata: dict[str, Any], context: grpc.aio.ServicerContext) -> None:
        self.guard, self.metrics, self.method, self.context = guard, metrics, method, context
        self.authorization = metadata.get("authorization")
        self.caller = guard.caller(grpc_peer_address(context.peer()),
                                   metadata.get("x-forwarded-for"), self.authorization)
        incoming = metadata.get("x-request-id")
        self.request_id = request_id(incoming if isinstance(incoming, str) else None)
        self.started = time.perf_counter()
        self.size = 0
        context.set_trailing_metadata((("x-request-id", self.request_id),))

    async def admit(self) -> None:
        """Check the caller; a refused call is aborted (counted in the metrics here, as
        the servicer never sees it)."""
        try:
            self.guard.check(self.method, self.caller, self.authorization)
        except Problem as problem:
            if self.metrics is not None:
                self.metrics.observe_request("grpc", self.method, problem.kind.grpc_code.name,
                                             time.perf_counter() - self.started)
            await abort_with(self.context, problem)

    def count(self, message: Any) -> None:
        size = getattr(message, "ByteSize", None)
        self.size += size() if callable(size) else 0

    def end(self, error: BaseException | None) -> None:
        """Log the call."""
        if isinstance(error, asyncio.CancelledError):
            code = grpc.StatusCode.CANCELLED
        else:
            code = self.context.code() or (grpc.StatusCode.OK if error is None
                                           else grpc.StatusCode.UNKNOWN)
        log_request(request_id=self.request_id, transport="grpc", method="POST",
                    route=self.method, path=self.method,
                    status=code.name if isinstance(code, grpc.StatusCode) else str(code),
                    bytes=self.size, ms=round((time.perf_counter() - self.started) * 1000, 1),
                    client=self.caller.address, key=self.caller.key)


class GrpcGuard(grpc.aio.ServerInterceptor):
    """A server interceptor applying a :class:`Guard`, request ids and access logs.

    Parameters
    ----------
    guard : Guard
        Shared with the REST app (one rate limit per caller across both).
    metrics : Metrics, optional
        Where refused calls are counted.
    """

    def __init__(self, guard: Guard, metrics: Metrics | None = None) -> None:
        self.guard = guard
        self.metrics = metrics

    async def intercept_service(
        self, continuation: Callable[[grpc.HandlerCallDetails],
                                     Awaitable[grpc.RpcMethodHandler]],
        handler_call_details: grpc.HandlerCallDetails,
    ) -> grpc.RpcMethodHandler:
        handler = await continuation(handler_call_details)
        if handler is None:
            return handler
        method = handler_call_details.method
        metadata = dict(handler_call_details.invocation_metadata or ())
        serde = {"request_deserializer": handler.request_deserializer,
                 "response_serializer": handler.response_serializer}
        if handler.unary_unary is not None:
            return grpc.unary_unary_rpc_method_handler(
                self._unary(handler.unary_unary, method, metadata), **serde)
        if handler.stream_unary is not None:
            return grpc.stream_unary_rpc_method_handler(
                self._unary(handler.stream_unary, method, metadata), **serde)
        if handler.unary_stream is not None:
            return grpc.unary_stream_rpc_method_handler(
                self._stream(handler.unary_stream, method, metadata), **serde)
        return grpc.stream_stream_rpc_method_handler(
            self._stream(handler.stream_stream, method, metadata), **serde)

    def _unary(self, behavior: Callable, method: str, metadata: dict[str, Any]) -> Callable:
        async def wrapped(request: Any, context: grpc.aio.ServicerContext) -> Any:
            call = _Call(self.guard, self.metrics, method, metadata, context)
            error: BaseException | None = None
            try:
                await call.admit()
                response = await behavior(request, context)
                call.count(response)
                return response
            except BaseException as raised:
                error = raised
                raise
            finally:
                call.end(error)

        return wrapped

    def _stream(self, behavior: Callable, method: str, metadata: dict[str, Any]) -> Callable:
        async def wrapped(request: Any, context: grpc.aio.ServicerContext
                          ) -> AsyncIterator[Any]:
            call = _Call(self.guard, self.metrics, method, metadata, context)
            error: BaseException | None = None
            try:
                await call.admit()
                async for response in behavior(request, context):
                    call.count(response)
                    yield response
            except BaseException as raised:
                error = raised
                raise
            finally:
                call.end(error)

        return wrapped
