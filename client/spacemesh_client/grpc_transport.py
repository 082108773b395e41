"""The gRPC transport (``proto/spacemesh.proto``), sync and async.

Chosen by the URL: ``grpc://host:8001`` (plaintext HTTP/2) or ``grpcs://host:443`` (TLS).
It needs the ``grpc`` extra: ``pip install 'spacemesh-client[grpc]'``.

Errors come back as a status code with the problem type in the trailing metadata
(``problem-type``, ``problem-status``, ``retry-after``, and the extension members as JSON
in ``problem-extensions``); :func:`error_from_rpc` turns them into the same exceptions as
the REST transport. A status without a problem type (the
channel could not connect, the client's deadline passed) becomes
:class:`~spacemesh_client.errors.ConnectionFailed` or
:class:`~spacemesh_client.errors.ClientTimeout`.

``health()`` asks ``grpc.health.v1.Health/Check``; the two one-field messages it uses are
encoded by hand so that grpcio-health-checking is not needed. The contract has no model
metadata call: ``model_info()`` raises :class:`~spacemesh_client.errors.Unimplemented`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any
from urllib.parse import urlsplit

from spacemesh_client._http import Health
from spacemesh_client._inputs import Arrays, Upload
from spacemesh_client.errors import (
    TYPE_BASE,
    ClientTimeout,
    ConnectionFailed,
    InvalidOption,
    InvalidRegion,
    PayloadTooLarge,
    SpaceMeshError,
    Unimplemented,
    error_from_problem,
    parse_retry_after,
)
from spacemesh_client.mesh import Mesh, MeshStats, repair_summary
from spacemesh_client.options import OPTION_NAMES, REPAIR_OPTION_NAMES
from spacemesh_client.progress import Reporter
from spacemesh_client.security import Verify, grpc_root_certificates

#: URL schemes of this transport.
SCHEMES = ("grpc", "grpcs")
#: Health service method and its SERVING status.
_HEALTH_CHECK = "/grpc.health.v1.Health/Check"
_SERVING = 1
#: Channel options: no client-side message size limit (the server enforces its own).
_CHANNEL_OPTIONS = [("grpc.max_receive_message_length", -1),
                    ("grpc.max_send_message_length", -1)]



def _modules() -> tuple[Any, Any, Any]:
    try:
        import grpc

        from spacemesh_client.pb import spacemesh_pb2, spacemesh_pb2_grpc
    except ModuleNotFoundError as error:
        raise ModuleNotFoundError(
            f"the gRPC transport needs {error.name}: pip install 'spacemesh-client[grpc]'"
        ) from None
    return grpc, spacemesh_pb2, spacemesh_pb2_grpc


def target_of(url: str) -> tuple[str, bool]:
    """``grpc://host:8001`` -> (``host:8001``, secure=False)."""
    parts = urlsplit(url)
    if parts.scheme not in SCHEMES or not parts.netloc:
        raise ValueError(f"not a gRPC URL: {url!r} (use grpc://host:port or grpcs://host:port)")
    return parts.netloc, parts.scheme == "grpcs"


def _health_status(data: bytes) -> int:
    """``HealthCheckResponse.status`` (field 1, varint) from its bytes."""
    return data[1] if len(data) >= 2 and data[0] == 0x08 else 0


# ---------------------------------------------------------------------- messages
def _set_options(request: Any, options: Mapping[str, Any]) -> Any:
    """``request`` with each option set on the field of its name.

    Raises
    ------
    InvalidOption
        What the server would answer (422 ``invalid-option``) for a value the field
        cannot hold (``raw="maybe"``, ``samples=2.5``); ranges are checked by the server.
    """
    for name, value in options.items():
        try:
            setattr(request, name, value)
        except (TypeError, ValueError) as error:
            raise InvalidOption(f"{name} cannot be {value!r} ({error})", status=422,
                                extra={"option": name}) from None
    return request


def generate_message(pb: Any, source: Upload | Arrays, fmt: str | None,
                     options: Mapping[str, Any]) -> Any:
    """A ``GenerateRequest`` (each option in the field of its name)."""
    request = _set_options(pb.GenerateRequest(format=fmt or ""), options)
    if isinstance(source, Upload):
        request.file.data = source.data
        request.file.filename = source.filename
    else:
        request.points.xyz.extend(source.points.reshape(-1).tolist())
        if source.normals is not None:
            request.points.normals.extend(source.normals.reshape(-1).tolist())
    return request


def region_message(pb: Any, region: Mapping[str, Any]) -> Any:
    """A ``Region`` from the JSON form of a region.

    Raises
    ------
    InvalidRegion
        What the server would answer (422 ``invalid-region``) for a region the message
        cannot hold: not exactly one known key, or values of the wrong type. Numbers
        the message holds are checked by the server.
    """
    forms = ("faces", "vertices", "sphere", "box", "auto")
    keys = [k for k in region if region[k] is not None]
    if len(keys) != 1 or keys[0] not in forms:
        raise InvalidRegion("the region must have exactly one of the keys "
                            + ", ".join(forms) + f", not {sorted(region)}", status=422)
    kind, value = keys[0], region[keys[0]]
    try:
        if kind == "auto":  # the proto field's name is no keyword of any language
            return pb.Region(auto_region=value)
        if kind in ("faces", "vertices"):
            return pb.Region(**{kind: pb.Indices(indices=[_index(i) for i in value])})
        if kind == "sphere":
            return pb.Region(sphere=pb.Sphere(center=list(value["center"]),
                                              radius=value["radius"]))
        return pb.Region(box=pb.Box(min=list(value["min"]), max=list(value["max"])))
    except (KeyError, TypeError, ValueError) as error:
        raise InvalidRegion(f"the {kind} region cannot be sent: {error!r}",
                            status=422) from None


def _index(value: Any) -> int:
    """An integer index (floats with a fraction, bools and strings refused)."""
    if isinstance(value, (bool, str, bytes)) or not float(value).is_integer():
        raise ValueError(f"{value!r} is not an integer index")
    return int(value)


def repair_message(pb: Any, mesh: Upload, region: Mapping[str, Any], fmt: str | None,
                   options: Mapping[str, Any], weld: bool = False) -> Any:
    """A ``RepairRequest`` (the region in any of its five forms)."""
    return _set_options(pb.RepairRequest(mesh=mesh.data, filename=mesh.filename,
                                         format=fmt or "", region=region_message(pb, region),
                                         weld=bool(weld)), options)


def _fields(message: Any) -> dict[str, Any]:
    """A message's fields by name (maps as dicts, repeated messages as lists of dicts;
    ``optional`` fields left unset are left out)."""
    out = {}
    for f in message.DESCRIPTOR.fields:
        if f.has_presence and f.message_type is None and not message.HasField(f.name):
            continue
        value = getattr(message, f.name)
        if hasattr(value, "items"):
            value = dict(value)
        elif f.message_type is not None and f.is_repeated:
            value = [_fields(item) for item in value]
        out[f.name] = value
    return out


def _reported_options(reply: Any) -> dict[str, Any]:
    """The resolved options of a ``MeshReply`` (a repair's: seed, steps, sampler)."""
    names = REPAIR_OPTION_NAMES if reply.HasField("repair") else OPTION_NAMES
    fields = reply.DESCRIPTOR.fields_by_name
    return {name: getattr(reply, name) for name in names
            if not fields[name].has_presence or reply.HasField(name)}


def mesh_from_reply(reply: Any) -> Mesh:
    """A :class:`Mesh` from a ``MeshReply``."""
    s = reply.stats
    stats = MeshStats(vertices=s.vertices, faces=s.faces, edges=s.edges,
                      face_degrees=dict(sorted(s.face_degrees.items())), manifold=s.manifold,
                      closed=s.closed, oriented=s.oriented, components=s.components,
                      genus=s.genus, fit=_fields(s.fit) if s.HasField("fit") else None)
    repair = repair_summary(_fields(reply.repair)) if reply.HasField("repair") else None
    return Mesh(data=reply.mesh, format=reply.format, stats=stats, seed=reply.seed,
                steps=reply.steps, sampler=reply.sampler,
                model=f"{reply.model_name}/{reply.model_version}",
                timings=dict(reply.timings), batch_size=reply.batch_size, repair=repair,
                options=_reported_options(reply),
                sample_scores=[(x.seed, x.score) for x in reply.sample_scores],
                points_reduced=({"read": reply.points_read, "used": reply.points_used}
                                if reply.HasField("points_read") else None))


def _extensions(text: str | None) -> dict[str, Any]:
    """``problem-extensions`` (JSON) -> the problem's extension members."""
    if not text:
        return {}
    try:
        data = json.loads(text)
    except ValueError:
        return {}
    return data if isinstance(data, dict) else {}


def error_from_rpc(error: Any, target: str) -> SpaceMeshError:
    """The exception for a failed call (a ``grpc.RpcError``)."""
    grpc = _modules()[0]
    metadata = {k: v for k, v in (error.trailing_metadata() or ())}
    code, details = error.code(), error.details() or ""
    type_uri = metadata.get("problem-type")
    if type_uri:
        status = metadata.get("problem-status", "")
        extensions = _extensions(metadata.get("problem-extensions"))
        problem = {**{k: v for k, v in extensions.items()
                      if k not in ("type", "title", "status", "detail", "instance")},
                   "type": type_uri, "detail": details,
                   "status": int(status) if status.isdigit() else None}
        return error_from_problem(problem, retry_after=parse_retry_after(
            metadata.get("retry-after")))
    if code == grpc.StatusCode.UNAVAILABLE:
        return ConnectionFailed(f"cannot reach {target}: {details}")
    if code == grpc.StatusCode.DEADLINE_EXCEEDED:
        return ClientTimeout(f"no answer from {target} within the client's timeout")
    if code == grpc.StatusCode.RESOURCE_EXHAUSTED:
        return PayloadTooLarge(details, status=413)
    if code == grpc.StatusCode.UNIMPLEMENTED:
        return Unimplemented(details, status=501)
    return SpaceMeshError(details, type=TYPE_BASE + "grpc-" + code.name.lower(),
                          title=f"gRPC {code.name}")


def _no_model_info(target: str) -> Unimplemented:
    return Unimplemented(f"{target}: the gRPC contract has no model metadata call; use the "
                         "REST URL (GET /v2/models/{name})", status=501)


class _Base:
    def __init__(self, url: str, timeout: float | None, metadata: Mapping[str, str] | None,
                 verify: Verify = True):
        self.grpc, self.pb, self.pb_grpc = _modules()
        self.url = url
        self.target, self.secure = target_of(url)
        self.timeout = timeout
        self.metadata = tuple((k.lower(), v) for k, v in (metadata or {}).items()) or None
        self.root_certificates = grpc_root_certificates(verify) if self.secure else None

    def _channel_args(self) -> tuple[tuple, dict]:
        if self.secure:
            credentials = self.grpc.ssl_channel_credentials(self.root_certificates)
            return (self.target, credentials), {"options": _CHANNEL_OPTIONS}
        return (self.target,), {"options": _CHANNEL_OPTIONS}

    def _call_kwargs(self) -> dict[str, Any]:
        return {"timeout": self.timeout, "metadata": self.metadata}


class GrpcTransport(_Base):
    """Blocking gRPC calls over one channel."""

    def __init__(self, url: str, *, timeout: float | None,
                 metadata: Mapping[str, str] | None = None, verify: Verify = True) -> None:
        super().__init__(url, timeout, metadata, verify)
        args, kwargs = self._channel_args()
        make = self.grpc.secure_channel if self.secure else self.grpc.insecure_channel
        self.channel = make(*args, **kwargs)
        self.stub = self.pb_grpc.SpaceMeshStub(self.channel)
        self._check = self.channel.unary_unary(
            _HEALTH_CHECK, request_serializer=lambda _: b"",
            response_deserializer=_health_status)

    def generate(self, source: Upload | Arrays, fmt: str | None, options: Mapping[str, Any],
                 progress: Reporter | None = None) -> Mesh:
        request = generate_message(self.pb, source, fmt, options)
        request.stages = progress is not None and progress.stage is not None
        try:
            if progress is None:
                return mesh_from_reply(self.stub.Generate(request, **self._call_kwargs()))
            for event in self.stub.GenerateStream(request, **self._call_kwargs()):
                if event.HasField("progress"):
                    progress(event.progress.stage, event.progress.step, event.progress.total)
                else:
                    return mesh_from_reply(event.mesh)
        except self.grpc.RpcError as error:
            raise error_from_rpc(error, self.target) from None
        raise ConnectionFailed(f"{self.target}: the stream ended without a mesh")

    def repair(self, mesh: Upload, region: Mapping[str, Any], fmt: str | None,
               options: Mapping[str, Any], weld: bool = False) -> Mesh:
        request = repair_message(self.pb, mesh, region, fmt, options, weld)
        try:
            return mesh_from_reply(self.stub.Repair(request, **self._call_kwargs()))
        except self.grpc.RpcError as error:
            raise error_from_rpc(error, self.target) from None

    def health(self) -> Health:
        try:
            status = self._check(None, **self._call_kwargs())
        except self.grpc.RpcError as error:
            raise error_from_rpc(error, self.target) from None
        return Health(live=True, ready=status == _SERVING)

    def model_info(self, name: str | None) -> dict[str, Any]:
        raise _no_model_info(self.target)

    def close(self) -> None:
        self.channel.close()


class AsyncGrpcTransport(_Base):
    """Non-blocking gRPC calls (``grpc.aio``) over one channel."""

    def __init__(self, url: str, *, timeout: float | None,
                 metadata: Mapping[str, str] | None = None, verify: Verify = True) -> None:
        super().__init__(url, timeout, metadata, verify)
        args, kwargs = self._channel_args()
        aio = self.grpc.aio
        make = aio.secure_channel if self.secure else aio.insecure_channel
        self.channel = make(*args, **kwargs)
        self.stub = self.pb_grpc.SpaceMeshStub(self.channel)
        self._check = self.channel.unary_unary(
            _HEALTH_CHECK, request_serializer=lambda _: b"",
            response_deserializer=_health_status)

    async def generate(self, source: Upload | Arrays, fmt: str | None,
                       options: Mapping[str, Any],
                       progress: Reporter | None = None) -> Mesh:
        request = generate_message(self.pb, source, fmt, options)
        request.stages = progress is not None and progress.stage is not None
        try:
            if progress is None:
                return mesh_from_reply(await self.stub.Generate(request, **self._call_kwargs()))
            async for event in self.stub.GenerateStream(request, **self._call_kwargs()):
                if event.HasField("progress"):
                    progress(event.progress.stage, event.progress.step, event.progress.total)
                else:
                    return mesh_from_reply(event.mesh)
        except self.grpc.RpcError as error:
            raise error_from_rpc(error, self.target) from None
        raise ConnectionFailed(f"{self.target}: the stream ended without a mesh")

    async def repair(self, mesh: Upload, region: Mapping[str, Any], fmt: str | None,
                     options: Mapping[str, Any], weld: bool = False) -> Mesh:
        request = repair_message(self.pb, mesh, region, fmt, options, weld)
        try:
            return mesh_from_reply(await self.stub.Repair(request, **self._call_kwargs()))
        except self.grpc.RpcError as error:
            raise error_from_rpc(error, self.target) from None

    async def health(self) -> Health:
        try:
            status = await self._check(None, **self._call_kwargs())
        except self.grpc.RpcError as error:
            raise error_from_rpc(error, self.target) from None
        return Health(live=True, ready=status == _SERVING)

    async def model_info(self, name: str | None) -> dict[str, Any]:
        raise _no_model_info(self.target)

    async def close(self) -> None:
        await self.channel.close()
