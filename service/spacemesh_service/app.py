"""The REST API (FastAPI): routes, problem+json errors, request metrics.

Routes: ``POST /generate`` (point cloud in, mesh out), ``POST /repair`` (a mesh and a
region in, the mesh with the region re-generated out), ``GET /v2``, ``/v2/health/live``,
``/v2/health/ready``, ``/v2/models/{name}``, ``/v2/models/{name}/ready``,
``/v2/models/{name}/versions/{version}``, ``/metrics``, and ``/docs`` + ``/openapi.json``.

:func:`create_app` builds the app around an :class:`~spacemesh_service.engine.Engine`.
Without one it makes its own and starts it in the app's lifespan, so
``uvicorn --factory spacemesh_service.app:create_app`` works; ``spacemesh serve``
(:mod:`spacemesh_service.server`) shares one engine between REST and gRPC.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from importlib.metadata import PackageNotFoundError, version
from typing import Any, TypeVar

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.utils import get_openapi
from fastapi.responses import JSONResponse, Response
from starlette.datastructures import UploadFile
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import Message, Receive

from spacemesh.io.limits import ReadLimits
from spacemesh_service import problems as P
from spacemesh_service.access_log import RestAccessLog
from spacemesh_service.connections import BodyTimeout
from spacemesh_service.engine import Engine, MeshUpload, ParseFn, Reply
from spacemesh_service.inputs import UploadRules, read_cloud_upload, read_json
from spacemesh_service.metrics import CONTENT_TYPE as METRICS_CONTENT_TYPE
from spacemesh_service.openapi import (
    DESCRIPTION,
    GENERATE_PARAMETERS,
    GENERATE_REQUEST_BODY,
    GENERATE_RESPONSES,
    REPAIR_PARAMETERS,
    REPAIR_REQUEST_BODY,
    REPAIR_RESPONSES,
    LiveModel,
    ModelReadyModel,
    ReadyModel,
    ServerMetadata,
    add_schemas,
)
from spacemesh_service.options import GENERATE_ROUTE_OPTIONS, REPAIR_ROUTE_OPTIONS
from spacemesh_service.problems import Problem, problem_response
from spacemesh_service.security import Guard, RestGuard, document_protection, without_paths
from spacemesh_service.settings import Settings
from spacemesh_service.streaming import stream_response, stream_responses
from spacemesh_service.ui import install_ui

log = logging.getLogger("spacemesh.service")

try:
    SERVICE_VERSION = version("spacemesh-service")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    SERVICE_VERSION = "0.0.0"



# ---------------------------------------------------------------------- errors
def problem_response_of(problem: Problem, request: Request | None = None) -> JSONResponse:
    """Render a :class:`Problem` as ``application/problem+json``."""
    instance = request.url.path if request is not None else None
    return JSONResponse(problem.to_dict(instance), status_code=problem.kind.status,
                        media_type=P.PROBLEM_MEDIA_TYPE, headers=problem.headers())


async def send_problem(problem: Problem, scope: dict[str, Any], send: Callable,
                       headers: dict[str, str]) -> None:
    """Answer a problem from ASGI middleware (before routing), with extra ``headers``."""
    response = problem_response_of(problem, Request(scope))
    response.headers.update(headers)
    await response(scope, _nothing_to_receive, send)


async def _nothing_to_receive() -> dict[str, Any]:  # pragma: no cover - never called
    return {"type": "http.disconnect"}


_HTTP_KINDS = {400: P.MALFORMED_INPUT, 404: P.NOT_FOUND, 405: P.METHOD_NOT_ALLOWED,
               413: P.PAYLOAD_TOO_LARGE, 415: P.UNSUPPORTED_FORMAT}


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(Problem)
    async def _problem(request: Request, problem: Problem) -> JSONResponse:
        return problem_response_of(problem, request)

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, error: RequestValidationError) -> JSONResponse:
        errors = [{"loc": list(e.get("loc", ())), "msg": e.get("msg", "")}
                  for e in error.errors()]
        detail = "; ".join(f"{'.'.join(map(str, e['loc'][1:])) or 'request'}: {e['msg']}"
                           for e in errors)
        return problem_response_of(Problem(P.INVALID_PARAMETER, detail, errors=errors), request)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, error: StarletteHTTPException) -> JSONResponse:
        kind = _HTTP_KINDS.get(error.status_code) or (
            P.INTERNAL if error.status_code >= 500 else P.INVALID_PARAMETER)
        problem = Problem(kind, str(error.detail))
        response = problem_response_of(problem, request)
        response.status_code = error.status_code
        response.headers.update(error.headers or {})  # Allow, on a 405
        return response

    @app.exception_handler(ClientDisconnected)
    async def _gone(request: Request, error: ClientDisconnected) -> Response:
        return Response(status_code=CLIENT_CLOSED_REQUEST)  # nobody reads it: for metrics

    @app.exception_handler(Exception)
    async def _internal(request: Request, error: Exception) -> JSONResponse:
        log.exception("unhandled error on %s", request.url.path)
        return problem_response_of(Problem(P.INTERNAL, "an unexpected error occurred"), request)


class RequestMetrics:
    """ASGI middleware: count requests by route template and status, time them."""

    def __init__(self, app: Callable[..., Awaitable[None]], engine: Engine) -> None:
        self.app = app
        self.engine = engine

    async def __call__(self, scope: dict[str, Any], receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        status = 500
        started = time.perf_counter()

        async def send_and_watch(message: dict[str, Any]) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, send_and_watch)
        finally:
            route = scope.get("route")
            path = getattr(route, "path", None) or "unmatched"
            self.engine.metrics.observe_request("http", path, str(status),
                                                time.perf_counter() - started)


# ---------------------------------------------------------------------- disconnects
#: Status recorded for a request whose client went away before its answer (nginx's
#: "client closed request"); the response is never sent.
CLIENT_CLOSED_REQUEST = 499

T = TypeVar("T")


class ClientDisconnected(Exception):
    """The client closed the connection before its answer was ready."""


async def _disconnected(receive: Receive) -> None:
    """Return when the client closes the connection (the body must have been read)."""
    while (await receive())["type"] != "http.disconnect":
        pass


async def unless_disconnected(request: Request, work: Awaitable[T]) -> T:
    """Await ``work``, cancelling it when the client disconnects first.

    Cancelling it cancels the request in the engine as gRPC cancels a call: it leaves the
    queue, or its batch stops at the next sampler step when nobody else waits for it.

    Parameters
    ----------
    request : Request
        Its body already read.
    work : awaitable
        The engine's ``generate`` or ``repair``.

    Returns
    -------
    What ``work`` returns.

    Raises
    ------
    ClientDisconnected
        The client went away first (answered as :data:`CLIENT_CLOSED_REQUEST`).
    """
    task = asyncio.ensure_future(work)
    watch = asyncio.ensure_future(_disconnected(request.receive))
    try:
        await asyncio.wait({task, watch}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        watch.cancel()
        if not task.done():
            task.cancel()
    if task.cancelled() or not task.done():
        with contextlib.suppress(asyncio.CancelledError, Problem):
            await task
        log.info("client went away; cancelled its %s request", request.url.path)
        raise ClientDisconnected
    return task.result()


# ---------------------------------------------------------------------- bodies
#: The multipart fields of each route that are not options: the point cloud file; the
#: mesh file and the region.
GENERATE_BODY_FIELDS = ("file",)
REPAIR_BODY_FIELDS = ("file", "region")

def _limited(request: Request, limit: int) -> Request:
    """The same request, its body reads raising 413 beyond ``limit`` bytes."""
    length = request.headers.get("content-length")
    if length is not None and length.isdigit() and int(length) > limit:
        raise Problem(P.PAYLOAD_TOO_LARGE, f"the body has {length} bytes; this server takes "
                      f"at most {limit}", limit=limit)
    received = 0
    receive = request.receive

    async def limited_receive() -> Message:
        nonlocal received
        message = await receive()
        if message["type"] == "http.request":
            received += len(message.get("body", b""))
            if received > limit:
                raise Problem(P.PAYLOAD_TOO_LARGE,
                              f"the body exceeds {limit} bytes", limit=limit)
        return message

    return Request(request.scope, limited_receive)


#: Bytes a repair's multipart body may hold besides its mesh file (the region, options).
_FORM_SLACK = 1 << 20


def _mesh_body_limit(settings: Settings) -> int:
    """The largest repair body: a mesh file of ``max_text_bytes`` and its form."""
    return min(settings.max_upload_bytes, settings.max_text_bytes + _FORM_SLACK)


def query_options(request: Request) -> dict[str, Any]:
    """Every query parameter, by name (values as sent): all of them are options, and
    :func:`~spacemesh_service.options.resolve_request` refuses the names the route does
    not take."""
    return dict(request.query_params)


def _form_options(form: Any, body_fields: tuple[str, ...]) -> dict[str, Any]:
    """The fields of a multipart form other than the route's ``body_fields`` (the file,
    the region): its options, by name (values as sent; the route refuses the names it
    does not take).

    Raises
    ------
    Problem
        422 ``invalid-option``: an option sent as a file part rather than a text field.
    """
    options = {}
    for name, value in form.multi_items():
        if name in body_fields:
            continue
        if not isinstance(value, str):
            raise Problem(P.INVALID_OPTION, f"{name} must be a text field, not a file",
                          option=name)
        options[name] = value
    return options


async def _read_request(request: Request, settings: Settings
                        ) -> tuple[ParseFn, dict[str, Any]]:
    """A parser of the request's point cloud, and the options found in a form.

    A multipart body is at most ``max_upload_bytes``; its file, which Starlette spools to
    a temporary file as it arrives, is read into memory only by the parser, in a parse
    slot (:class:`~spacemesh_service.inputs.ParseSlots`), so the uploads waiting for a
    slot are held on disk, not in memory. A JSON body is at most ``max_text_bytes``.
    """
    content_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if content_type == "multipart/form-data":
        body_request = _limited(request, settings.max_upload_bytes)
        form = await body_request.form(max_files=1,
                                       max_fields=len(GENERATE_ROUTE_OPTIONS) + 4)
        try:
            upload = form.get("file")
            if not isinstance(upload, UploadFile):
                raise Problem(P.MALFORMED_INPUT, "the multipart body has no file field 'file'")
            spooled, filename = upload.file, upload.filename
            options = _form_options(form, GENERATE_BODY_FIELDS)
        except BaseException:
            await form.close()
            raise

        def parse_file(limits: ReadLimits, rules: UploadRules
                       ) -> tuple[Any, Any, str, dict[str, Any], int | None]:
            try:  # the spooled file is read here, in the parse slot, and closed after
                spooled.seek(0)
                data = spooled.read()
            finally:
                spooled.close()
            points, normals, source, count = read_cloud_upload(data, filename, limits, rules)
            return points, normals, source, {}, count

        return parse_file, options
    if content_type == "application/json" or content_type.endswith("+json"):
        limit = min(settings.max_upload_bytes, settings.max_text_bytes)
        body = await _limited(request, limit).body()

        def parse(limits: ReadLimits, _: UploadRules
                  ) -> tuple[Any, Any, str, dict[str, Any], int | None]:
            points, normals, options = read_json(body, limits)
            return points, normals, "json", options, None

        return parse, {}
    shown = content_type or "no Content-Type"
    raise Problem(P.UNSUPPORTED_FORMAT, f"cannot read a {shown} body; send multipart/form-data "
                  "with a 'file' field, or application/json with 'points'")


async def _read_repair_form(request: Request, limit: int
                            ) -> tuple[MeshUpload, str | bytes, dict[str, Any]]:
    """The mesh file (field ``file``), the region's JSON (field ``region``, text or a
    file) and the options found in a repair request's multipart form."""
    content_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if content_type != "multipart/form-data":
        shown = content_type or "no Content-Type"
        raise Problem(P.UNSUPPORTED_FORMAT, f"cannot read a {shown} body; send "
                      "multipart/form-data with the mesh in 'file' and the region (JSON) "
                      "in 'region'")
    form = await _limited(request, limit).form(max_files=2,
                                               max_fields=len(REPAIR_ROUTE_OPTIONS) + 4)
    try:
        upload = form.get("file")
        if not isinstance(upload, UploadFile):
            raise Problem(P.MALFORMED_INPUT, "the multipart body has no file field 'file' "
                          "(the mesh)")
        field = form.get("region")
        if field is None:
            raise Problem(P.MALFORMED_INPUT, "the multipart body has no field 'region' (the "
                          'region as JSON, e.g. {"faces": [0, 1]})')
        region = await field.read() if isinstance(field, UploadFile) else field
        mesh = MeshUpload(await upload.read(), upload.filename)
        options = _form_options(form, REPAIR_BODY_FIELDS)
    finally:
        await form.close()
    return mesh, region, options


def _generated_name(reply: Reply) -> str:
    return f"spacemesh-{reply.seed}.{reply.mesh.format}"


def _repaired_name(reply: Reply) -> str:
    return f"spacemesh-repair-{reply.seed}.{reply.mesh.format}"


# ---------------------------------------------------------------------- app
def create_app(settings: Settings | None = None, *, engine: Engine | None = None,
               guard: Guard | None = None) -> FastAPI:
    """The REST app.

    Parameters
    ----------
    settings : Settings, optional
        Default :meth:`Settings.from_env`.
    engine : Engine, optional
        Shared with the gRPC server and started by its owner; without one, the app makes
        one and starts/drains it in its lifespan.
    guard : Guard, optional
        API keys and rate limits (shared with the gRPC server); default: from
        ``settings``.

    Returns
    -------
    FastAPI
    """
    settings = settings or (engine.settings if engine else Settings.from_env())
    owns_engine = engine is None
    engine = engine or Engine(settings)

    @contextlib.asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        if owns_engine:
            await engine.start()
        yield
        if owns_engine:
            await engine.stop(settings.drain_timeout_s)

    app = FastAPI(title="SpaceMesh", version=SERVICE_VERSION, description=DESCRIPTION,
                  lifespan=lifespan)
    app.state.engine = engine
    guard = guard or Guard.from_settings(settings)
    app.add_middleware(BodyTimeout, seconds=settings.body_timeout_s)
    app.add_middleware(RestGuard, guard=guard, send_problem=send_problem)
    app.add_middleware(RequestMetrics, engine=engine)
    if settings.access_log:
        app.add_middleware(RestAccessLog)
    _install_error_handlers(app)

    @app.post("/generate", tags=["generate"], response_class=Response,
              summary="Generate a mesh from a point cloud",
              openapi_extra={"requestBody": GENERATE_REQUEST_BODY,
                             "parameters": GENERATE_PARAMETERS},
              responses=GENERATE_RESPONSES)
    async def generate(request: Request) -> Response:
        """Point cloud in, oriented manifold polygon mesh out.

        The body is a multipart upload (field `file`) or JSON `{"points": ...}`. Options
        in the body take precedence over the query string. Every option error answers 422
        `invalid-option` naming the option (`option`): a value of the wrong type
        (integer options take only integers: `seed=1e3` is refused), out of range, or a
        name this route does not take (`unknown` lists them).
        """
        with engine.admit():
            parse, form_options = await _read_request(request, settings)
            options = {**query_options(request), **form_options}
            reply = await unless_disconnected(request, engine.generate(parse, options))
        headers = reply.headers()
        headers["Content-Disposition"] = f'inline; filename="{_generated_name(reply)}"'
        return Response(reply.mesh.body, media_type=reply.mesh.media_type, headers=headers)

    @app.post("/repair", tags=["repair"], response_class=Response,
              summary="Re-generate a region of a mesh",
              openapi_extra={"requestBody": REPAIR_REQUEST_BODY,
                             "parameters": REPAIR_PARAMETERS},
              responses=REPAIR_RESPONSES)
    async def repair(request: Request) -> Response:
        """A mesh and a region in; the region's vertices and faces generated again, every
        other face unchanged.

        The body is multipart: the mesh file in `file` (OBJ, OFF, PLY, STL, GLB, glTF) and
        the region as JSON in `region`: `{"faces": [...]}`, `{"vertices": [...]}`,
        `{"sphere": {"center": [x, y, z], "radius": r}}` or
        `{"box": {"min": [x, y, z], "max": [x, y, z]}}` (mesh coordinates, indices into
        the file's faces and vertices). Options `format`, `seed`, `steps`, `sampler` as
        for `/generate`, and `weld`, `max_growth`, in the query or the form (the form
        wins); any other name, generate-only options included, is 422 `invalid-option`. With
        `weld=true`, vertices at exactly equal positions are merged first (vertex indices
        of the region stay the file's); the output is the welded mesh repaired and
        `X-SpaceMesh-Welded-Vertices` says how many vertices were merged away. A region
        the server cannot use answers 422 with its kind as the problem type, before the
        request is queued.
        """
        with engine.admit():
            upload, region, form_options = await _read_repair_form(
                request, _mesh_body_limit(settings))
            options = {**query_options(request), **form_options}
            reply = await unless_disconnected(request, engine.repair(upload, region, options))
        headers = reply.headers()
        headers["Content-Disposition"] = f'inline; filename="{_repaired_name(reply)}"'
        return Response(reply.mesh.body, media_type=reply.mesh.media_type, headers=headers)

    @app.post("/generate/stream", tags=["generate"], response_class=Response,
              summary="Generate a mesh, with progress events (Server-Sent Events)",
              openapi_extra={"requestBody": GENERATE_REQUEST_BODY,
                             "parameters": GENERATE_PARAMETERS},
              responses=stream_responses(GENERATE_RESPONSES))
    async def generate_stream(request: Request) -> Response:
        """`POST /generate` with its progress as Server-Sent Events (`text/event-stream`).

        The same body and options. Once the request is decoded and queued the answer is
        a stream of `progress` events, then one `result` event (the mesh in base64 and
        the headers of `/generate`) or one `problem` event (problem+json). An error
        before that is a plain problem+json response.
        """
        async def work(progress: Any, stage: Any) -> Reply:
            parse, form_options = await _read_request(request, settings)
            options = {**query_options(request), **form_options}
            return await engine.generate(parse, options, progress=progress, stage=stage)

        return await stream_response(request, engine, work, _generated_name)

    @app.post("/repair/stream", tags=["repair"], response_class=Response,
              summary="Re-generate a region of a mesh, with progress events",
              openapi_extra={"requestBody": REPAIR_REQUEST_BODY,
                             "parameters": REPAIR_PARAMETERS},
              responses=stream_responses(REPAIR_RESPONSES))
    async def repair_stream(request: Request) -> Response:
        """`POST /repair` with its progress as Server-Sent Events, as `/generate/stream`."""
        async def work(progress: Any, stage: Any) -> Reply:
            upload, region, form_options = await _read_repair_form(
                request, _mesh_body_limit(settings))
            options = {**query_options(request), **form_options}
            return await engine.repair(upload, region, options, progress=progress,
                                       stage=stage)

        return await stream_response(request, engine, work, _repaired_name)

    @app.get("/v2", tags=["health"], response_model=ServerMetadata)
    async def server_metadata() -> dict[str, Any]:
        """KServe v2 server metadata."""
        return {"name": "spacemesh", "version": SERVICE_VERSION, "extensions": []}

    @app.get("/v2/health/live", tags=["health"], response_model=LiveModel)
    async def live() -> dict[str, bool]:
        """The process is up."""
        return {"live": True}

    @app.get("/v2/health/ready", tags=["health"], response_model=ReadyModel,
             responses={503: {"description": "Loading, warming up, draining, or the worker "
                                             "stuck or saturated (the detail says which)",
                              "model": ReadyModel}})
    async def ready() -> JSONResponse:
        """Models loaded, a warm-up inference passed, and new work would be done within
        the request deadline (503 otherwise: loading, draining, stuck or saturated)."""
        ready, detail = engine.readiness()
        body: dict[str, Any] = {"ready": ready}
        if detail:  # failed to load, or stuck / saturated: say why
            body["detail"] = detail
        return JSONResponse(body, status_code=200 if ready else 503)

    def _model(name: str, version: str | None = None) -> dict[str, Any]:
        if engine.generator is None:
            raise Problem(P.NOT_READY, "the model is loading", retry_after=1)
        if name != engine.model_name or (version is not None
                                         and version != engine.model_version):
            wanted = name if version is None else f"{name} version {version}"
            raise Problem(P.MODEL_NOT_FOUND, f"no model {wanted}; this server has "
                          f"{engine.model_name} version {engine.model_version}")
        return without_paths(engine.metadata())

    model_errors: dict[int | str, dict[str, Any]] = {404: problem_response("No such model", {
        "missing": (P.MODEL_NOT_FOUND, "no model foo")})}

    @app.get("/v2/models/{name}", tags=["models"], responses=model_errors)
    async def model_metadata(name: str) -> dict[str, Any]:
        """Versions, limits, input formats, the training data card and metrics."""
        return _model(name)

    @app.get("/v2/models/{name}/versions/{version}", tags=["models"], responses=model_errors)
    async def model_version_metadata(name: str, version: str) -> dict[str, Any]:
        """The same, for one version."""
        return _model(name, version)

    @app.get("/v2/models/{name}/ready", tags=["models"], response_model=ModelReadyModel,
             responses=model_errors)
    async def model_ready(name: str) -> JSONResponse:
        """Whether this model is ready (503 otherwise)."""
        _model(name)
        return JSONResponse({"name": name, "ready": engine.ready},
                            status_code=200 if engine.ready else 503)

    @app.get("/metrics", tags=["health"], response_class=Response,
             responses={200: {"content": {METRICS_CONTENT_TYPE: {}},
                              "description": "Prometheus text format"}})
    async def metrics() -> Response:
        """Prometheus metrics."""
        return Response(engine.metrics.render(), media_type=METRICS_CONTENT_TYPE)

    if settings.ui:  # the web page at / (spacemesh_service.ui)
        install_ui(app, engine, _limited)

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            spec = get_openapi(title=app.title, version=app.version,
                               description=app.description, routes=app.routes)
            app.openapi_schema = document_protection(add_schemas(spec), guard)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
    return app
