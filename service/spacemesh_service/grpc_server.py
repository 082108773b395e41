"""The gRPC API (``proto/spacemesh.proto``), a thin adapter over the shared engine.

``Generate`` and ``GenerateStream`` call :meth:`Engine.generate` exactly as
``POST /generate`` does, and ``Repair`` calls :meth:`Engine.repair` as ``POST /repair``
does, so inputs, errors and mesh bytes are the same. A
:class:`~spacemesh_service.problems.Problem` ends the call with its gRPC status code and
trailing metadata ``problem-type`` / ``problem-status`` (and ``retry-after``).
``grpc.health.v1`` reports SERVING for ``""`` and ``spacemesh.v1.SpaceMesh`` once the
model is ready, and NOT_SERVING while loading or draining.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import AsyncIterator
from dataclasses import asdict
from typing import Any

import grpc
from grpc_health.v1 import health_pb2, health_pb2_grpc
from grpc_health.v1.health import aio as health_aio

from spacemesh.io.limits import ReadLimits
from spacemesh_service import problems as P
from spacemesh_service.connections import Tls, grpc_credentials, grpc_options
from spacemesh_service.engine import Engine, MeshUpload, ParseFn, Reply
from spacemesh_service.grpc_guard import GrpcGuard, abort_with
from spacemesh_service.inputs import UploadRules, points_from_flat, read_cloud_upload
from spacemesh_service.options import GENERATE_ROUTE_OPTIONS, REPAIR_ROUTE_OPTIONS, grpc_values
from spacemesh_service.outputs import MeshStats
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from spacemesh_service.problems import Problem
from spacemesh_service.security import Guard
from spacemesh_service.streaming import ProgressEvents, next_event

log = logging.getLogger("spacemesh.service")

#: Full name of the service (also its grpc.health.v1 service name).
SERVICE_NAME = pb.DESCRIPTOR.services_by_name["SpaceMesh"].full_name
#: Bytes a message may have beyond the upload limit (the other fields).
_MESSAGE_SLACK = 1 << 20


def repair_stats_to_pb(summary: dict[str, Any]) -> pb.RepairStats:
    """The gRPC form of a repair summary (:func:`spacemesh_service.outputs.repair_summary`)."""
    fields = pb.RepairStats.DESCRIPTOR.fields_by_name
    values = {k: v for k, v in summary.items() if k in fields}
    if "new_face_degrees" in values:
        values["new_face_degrees"] = {int(k): v for k, v in values["new_face_degrees"].items()}
    return pb.RepairStats(**values)


def stats_to_pb(stats: MeshStats) -> pb.MeshStats:
    """The gRPC form of a mesh's statistics (its fit report: the same field names)."""
    values = asdict(stats)
    fit = values.pop("fit")
    message = pb.MeshStats(**values)
    if fit is not None:
        message.fit.CopyFrom(pb.FitReport(**fit))
    return message


def reply_to_pb(reply: Reply) -> pb.MeshReply:
    """The gRPC form of an engine reply (the resolved options: the fields of the same
    names)."""
    message = pb.MeshReply(
        mesh=reply.mesh.body, format=reply.mesh.format, media_type=reply.mesh.media_type,
        stats=stats_to_pb(reply.mesh.stats), model_name=reply.model_name,
        model_version=reply.model_version, timings=reply.timings,
        batch_size=reply.batch_size,
        **{k: v for k, v in reply.options.items() if v is not None},
        sample_scores=[pb.SampleScore(seed=seed, score=score)
                       for seed, score in reply.sample_scores],
    )
    if reply.repair is not None:
        message.repair.CopyFrom(repair_stats_to_pb(reply.repair))
    if reply.input_kind is not None:
        message.input_kind = reply.input_kind
    if reply.reduction is not None:
        message.points_read = int(reply.reduction["read"])
        message.points_used = int(reply.reduction["used"])
    return message


def reduction_metadata(reply: Reply, context: grpc.aio.ServicerContext) -> None:
    """Add ``x-spacemesh-points-read`` and ``x-spacemesh-points-used`` to the call's
    trailing metadata when the upload's points were reduced (REST: the
    ``X-SpaceMesh-Points-*`` headers)."""
    if reply.reduction is None:
        return
    kept = tuple(context.trailing_metadata() or ())
    context.set_trailing_metadata((*kept,
                                   ("x-spacemesh-points-read", str(reply.reduction["read"])),
                                   ("x-spacemesh-points-used", str(reply.reduction["used"]))))


def request_parser(request: pb.GenerateRequest, max_bytes: int) -> ParseFn:
    """The engine's parse function for a GenerateRequest (file bytes or numbers)."""
    which = request.WhichOneof("input")
    if which == "file":
        data, filename = request.file.data, request.file.filename or None
        if len(data) > max_bytes:
            raise Problem(P.PAYLOAD_TOO_LARGE, f"the file has {len(data)} bytes; this server "
                          f"takes at most {max_bytes}", limit=max_bytes)
        def parse_file(limits: ReadLimits, rules: UploadRules
                       ) -> tuple[Any, Any, str, dict[str, Any], int | None]:
            points, normals, source, count = read_cloud_upload(data, filename, limits, rules)
            return points, normals, source, {}, count

        return parse_file
    if which == "points":
        xyz, normals = request.points.xyz, request.points.normals
        return lambda limits, _: (*points_from_flat(xyz, normals, limits), "points", {}, None)
    raise Problem(P.MALFORMED_INPUT, "the request has no input: set 'file' or 'points'")


def region_from_pb(region: pb.Region) -> dict[str, Any]:
    """The JSON form of a ``Region`` message (checked by :func:`read_region` later)."""
    shape = region.WhichOneof("shape")
    if shape in ("faces", "vertices"):
        return {shape: list(getattr(region, shape).indices)}
    if shape == "sphere":
        return {"sphere": {"center": list(region.sphere.center),
                           "radius": region.sphere.radius}}
    if shape == "box":
        return {"box": {"min": list(region.box.min), "max": list(region.box.max)}}
    if shape == "auto_region":
        return {"auto": region.auto_region}
    raise Problem(P.MALFORMED_INPUT, "the region has no shape: set faces, vertices, sphere, "
                  "box or auto_region")


def repair_input(request: pb.RepairRequest, max_bytes: int) -> tuple[MeshUpload, dict]:
    """The mesh and the region (JSON form) of a RepairRequest."""
    if len(request.mesh) > max_bytes:
        raise Problem(P.PAYLOAD_TOO_LARGE, f"the mesh has {len(request.mesh)} bytes; this "
                      f"server takes at most {max_bytes}", limit=max_bytes)
    if request.HasField("region"):
        if len(request.faces):
            raise Problem(P.INVALID_REGION, "set either 'region' or 'faces', not both")
        region = region_from_pb(request.region)
    elif len(request.faces):
        region = {"faces": list(request.faces)}
    else:
        raise Problem(P.MALFORMED_INPUT, "the request has no region: set 'region' (or "
                      "'faces')")
    return MeshUpload(request.mesh, request.filename or None), region


class SpaceMeshServicer(pb_grpc.SpaceMeshServicer):
    """``spacemesh.v1.SpaceMesh`` over an :class:`Engine`."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    @contextlib.asynccontextmanager
    async def _call(self, method: str, context: grpc.aio.ServicerContext
                    ) -> AsyncIterator[None]:
        """Run one call: admit it, end it with its problem's status and metadata, and
        count it by its final status code.

        A :class:`Problem` ends the call with its kind's code; any other exception is
        logged and ends it as INTERNAL with the ``internal-error`` problem (as REST
        answers 500); a cancelled call counts as CANCELLED.
        """
        started, code = time.perf_counter(), grpc.StatusCode.OK
        try:
            with self.engine.admit():
                yield
        except asyncio.CancelledError:
            code = grpc.StatusCode.CANCELLED
            raise
        except Exception as error:
            if isinstance(error, Problem):
                problem = error
            else:
                log.exception("unhandled error in %s", method)
                problem = Problem(P.INTERNAL, "an unexpected error occurred")
            code = problem.kind.grpc_code
            await abort_with(context, problem)  # keeps the request id
        finally:
            self.engine.metrics.observe_request("grpc", f"/{SERVICE_NAME}/{method}", code.name,
                                                time.perf_counter() - started)

    async def Generate(self, request: pb.GenerateRequest,
                       context: grpc.aio.ServicerContext) -> pb.MeshReply:
        async with self._call("Generate", context):
            parse = request_parser(request, self.engine.settings.max_upload_bytes)
            reply = await self.engine.generate(parse, grpc_values(request,
                                                                  GENERATE_ROUTE_OPTIONS))
            reduction_metadata(reply, context)
            return reply_to_pb(reply)

    async def GenerateStream(self, request: pb.GenerateRequest,
                             context: grpc.aio.ServicerContext) -> AsyncIterator[pb.GenerateEvent]:
        events = ProgressEvents()  # the SSE stream's stage and step reports
        task: asyncio.Task | None = None
        async with self._call("GenerateStream", context):
            try:
                parse = request_parser(request, self.engine.settings.max_upload_bytes)
                task = asyncio.ensure_future(self.engine.generate(
                    parse, grpc_values(request, GENERATE_ROUTE_OPTIONS),
                    progress=events.step, stage=events.stage))
                while (event := await next_event(events, task)) is not None:
                    if not request.stages and not (event["stage"] == "sampler"
                                                   and event["done"] > 0):
                        continue  # steps only, as older clients expect
                    yield pb.GenerateEvent(progress=pb.Progress(
                        step=event["done"], total=event["total"], stage=event["stage"],
                        fraction=event["fraction"]))
                reply = task.result()  # raises the request's Problem
                reduction_metadata(reply, context)
                yield pb.GenerateEvent(mesh=reply_to_pb(reply))
            finally:
                if task is not None and not task.done():
                    task.cancel()
                    with contextlib.suppress(asyncio.CancelledError, Problem):
                        await task

    async def Repair(self, request: pb.RepairRequest,
                     context: grpc.aio.ServicerContext) -> pb.MeshReply:
        async with self._call("Repair", context):
            upload, region = repair_input(request, self.engine.settings.max_upload_bytes)
            reply = await self.engine.repair(upload, region,
                                             grpc_values(request, REPAIR_ROUTE_OPTIONS))
            return reply_to_pb(reply)


class GrpcServer:
    """The gRPC server: SpaceMesh service and grpc.health.v1, on one port.

    Parameters
    ----------
    engine : Engine
    guard : Guard, optional
        API keys and rate limits (shared with the REST app); default: from the settings.
    tls : Tls, optional
        Serve over TLS with this certificate (plaintext without).
    """

    def __init__(self, engine: Engine, *, guard: Guard | None = None,
                 tls: Tls | None = None) -> None:
        settings = engine.settings
        size = settings.max_upload_bytes + _MESSAGE_SLACK
        interceptors = [GrpcGuard(guard or Guard.from_settings(settings), engine.metrics)]
        self.server = grpc.aio.server(interceptors=interceptors, options=[
            ("grpc.max_receive_message_length", size),
            ("grpc.max_send_message_length", size),
            *grpc_options(settings),
        ])
        self._credentials = grpc_credentials(tls)
        pb_grpc.add_SpaceMeshServicer_to_server(SpaceMeshServicer(engine), self.server)
        self.health = health_aio.HealthServicer()
        health_pb2_grpc.add_HealthServicer_to_server(self.health, self.server)
        self.port: int | None = None
        self._address = settings.host

    async def start(self, port: int) -> int:
        """Listen (port 0: any free port) and report NOT_SERVING; returns the port."""
        for service in ("", SERVICE_NAME):
            await self.health.set(service, health_pb2.HealthCheckResponse.NOT_SERVING)
        host = f"[{self._address}]" if ":" in self._address else self._address
        address = f"{host}:{port}"
        self.port = (self.server.add_insecure_port(address) if self._credentials is None
                     else self.server.add_secure_port(address, self._credentials))
        if not self.port:
            raise OSError(f"cannot listen for gRPC on {host}:{port}")
        await self.server.start()
        return self.port

    async def set_serving(self) -> None:
        """Report SERVING (the model is ready)."""
        for service in ("", SERVICE_NAME):
            await self.health.set(service, health_pb2.HealthCheckResponse.SERVING)

    async def set_not_serving(self) -> None:
        """Report NOT_SERVING (draining: new calls get UNAVAILABLE from the engine)."""
        for service in ("", SERVICE_NAME):
            await self.health.set(service, health_pb2.HealthCheckResponse.NOT_SERVING)

    async def stop(self, grace: float) -> None:
        """NOT_SERVING, refuse new calls, let running ones finish within ``grace`` s."""
        await self.health.enter_graceful_shutdown()
        await self.server.stop(grace)
