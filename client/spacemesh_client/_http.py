"""The REST transport (httpx), sync and async: requests out, meshes and errors in.

The two transports share everything but the I/O: :func:`generate_request` and
:func:`repair_request` build a :class:`Call`, :func:`mesh_from_response` and
:func:`error_from_http` read the answer, and :func:`translate` maps httpx's exceptions
to :class:`~spacemesh_client.errors.ConnectionFailed` and
:class:`~spacemesh_client.errors.ClientTimeout`.
"""

from __future__ import annotations

import base64
import contextlib
import json
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote

import httpx

from spacemesh_client._formats import MEDIA_TYPES
from spacemesh_client._inputs import Arrays, Upload
from spacemesh_client.errors import (
    ClientTimeout,
    ConnectionFailed,
    error_from_http,
    error_from_problem,
)
from spacemesh_client.mesh import (
    HEADER_PREFIX,
    Mesh,
    MeshStats,
    repair_summary,
    sample_scores_from_text,
)
from spacemesh_client.options import options_from_headers, query_params
from spacemesh_client.security import Verify, http_verify

_FORMAT_OF_MEDIA = {v: k for k, v in MEDIA_TYPES.items()}
#: The model ``model_info()`` asks for when the server does not list its models.
DEFAULT_MODEL = "spacemesh-small"


@dataclass(frozen=True)
class Health:
    """``GET /v2/health/live`` and ``/v2/health/ready`` (or grpc.health.v1).

    Attributes
    ----------
    live : bool
        The process answers.
    ready : bool
        The model is loaded and warm, and the server is not draining.
    """

    live: bool
    ready: bool


@dataclass(frozen=True)
class Call:
    """One HTTP request, ready for ``httpx.Client.request(**call.kwargs())``."""

    method: str
    path: str
    params: dict[str, Any] = field(default_factory=dict)
    content: bytes | None = None
    headers: dict[str, str] | None = None
    files: dict[str, tuple[str, bytes, str]] | None = None
    data: dict[str, str] | None = None

    def kwargs(self) -> dict[str, Any]:
        out: dict[str, Any] = {"method": self.method, "url": self.path}
        for name in ("params", "content", "headers", "files", "data"):
            value = getattr(self, name)
            if value:
                out[name] = value
        return out


def _params(fmt: str | None, options: Mapping[str, Any]) -> dict[str, Any]:
    return {**({"format": fmt} if fmt is not None else {}), **query_params(options)}


def generate_request(source: Upload | Arrays, fmt: str | None,
                     options: Mapping[str, Any], stream: bool = False) -> Call:
    """``POST /generate``: a multipart upload, or JSON points; the format and the generate
    options (:data:`~spacemesh_client.options.GENERATE_OPTIONS`) in the query.
    ``stream``: ``POST /generate/stream`` (Server-Sent Events, :class:`EventReader`)."""
    params = _params(fmt, options)
    path = "/generate/stream" if stream else "/generate"
    if isinstance(source, Upload):
        files = {"file": (source.filename, source.data, "application/octet-stream")}
        return Call("POST", path, params, files=files)
    body: dict[str, Any] = {"points": source.points.tolist()}
    if source.normals is not None:
        body["normals"] = source.normals.tolist()
    # Python's JSON: exact floats (shortest repr), and NaN/Infinity written as such, so the
    # server, not the client, decides what is wrong with them (422 non-finite).
    content = json.dumps(body, separators=(",", ":")).encode()
    return Call("POST", path, params, content=content,
                headers={"content-type": "application/json"})


def repair_request(mesh: Upload, region: Mapping[str, Any], fmt: str | None,
                   options: Mapping[str, Any], weld: bool = False) -> Call:
    """``POST /repair``: the mesh as multipart field ``file``, the region as field
    ``region`` (JSON); options and ``weld=true`` (when asked for) in the query."""
    files = {"file": (mesh.filename, mesh.data, "application/octet-stream")}
    params = _params(fmt, options)
    if weld:
        params["weld"] = "true"
    return Call("POST", "/repair", params, files=files,
                data={"region": json.dumps(dict(region))})


def _timings(server_timing: str) -> dict[str, float]:
    """``Server-Timing: queue;dur=1.5, sampler;dur=20.1`` -> seconds per stage."""
    out = {}
    for item in server_timing.split(","):
        name, _, rest = item.strip().partition(";")
        for param in rest.split(";"):
            key, _, value = param.strip().partition("=")
            if key == "dur" and name:
                with contextlib.suppress(ValueError):
                    out[name] = float(value) / 1000
    return out


def _int(text: str | None) -> int | None:
    try:
        return int(text) if text is not None else None
    except ValueError:
        return None


def _repair(text: str | None) -> dict[str, Any] | None:
    """``X-SpaceMesh-Repair`` (JSON) -> :attr:`Mesh.repair`."""
    if not text:
        return None
    try:
        data = json.loads(text)
    except ValueError:
        return None
    return repair_summary(data) if isinstance(data, dict) else None


def mesh_from_response(response: httpx.Response, fmt: str | None) -> Mesh:
    """A :class:`Mesh` from a successful ``/generate`` or ``/repair`` response."""
    headers = response.headers
    if fmt is None:
        media = headers.get("content-type", "").split(";")[0].strip().lower()
        fmt = _FORMAT_OF_MEDIA.get(media, "glb")
    return Mesh(
        data=response.content, format=fmt, stats=MeshStats.from_headers(headers),
        seed=_int(headers.get(HEADER_PREFIX + "seed")),
        steps=_int(headers.get(HEADER_PREFIX + "steps")),
        sampler=headers.get(HEADER_PREFIX + "sampler", ""),
        model=headers.get(HEADER_PREFIX + "model", ""),
        timings=_timings(headers.get("server-timing", "")),
        batch_size=_int(headers.get(HEADER_PREFIX + "batch-size")) or 0,
        repair=_repair(headers.get(HEADER_PREFIX + "repair")),
        options=options_from_headers(headers),
        sample_scores=sample_scores_from_text(headers.get(HEADER_PREFIX + "sample-scores", "")),
        points_reduced=_reduced(headers),
    )


def _reduced(headers: httpx.Headers) -> dict[str, int] | None:
    """``{"read": ..., "used": ...}`` from ``X-SpaceMesh-Points-Read`` / ``-Used`` (None
    when the points were not reduced)."""
    read = _int(headers.get(HEADER_PREFIX + "points-read"))
    used = _int(headers.get(HEADER_PREFIX + "points-used"))
    return None if read is None or used is None else {"read": read, "used": used}


class EventReader:
    """Reads the Server-Sent Events of ``/generate/stream`` line by line.

    ``progress(stage, done, total)`` (a :class:`~spacemesh_client.progress.Reporter`)
    is called for each progress event (as over gRPC); the
    ``result`` event becomes the response the plain route would have given, and a
    ``problem`` event raises its typed error.

    Parameters
    ----------
    progress : callable
    """

    def __init__(self, progress: Callable[[str, int, int], None]) -> None:
        self.progress = progress
        self.name: str | None = None
        self.data: list[str] = []
        self.result: httpx.Response | None = None

    def feed(self, line: str) -> None:
        """One line of the stream (without its end of line)."""
        if line.startswith("event:"):
            self.name = line[6:].strip()
        elif line.startswith("data:"):
            self.data.append(line[5:].strip())
        elif not line and self.name is not None:
            name, data = self.name, json.loads("\n".join(self.data))
            self.name, self.data = None, []
            self._event(name, data)

    def _event(self, name: str, data: dict[str, Any]) -> None:
        if name == "progress":
            self.progress(str(data.get("stage", "")), int(data["done"]), int(data["total"]))
        elif name == "problem":
            raise error_from_problem(data, status=int(data.get("status") or 500))
        elif name == "result":
            headers = {**data["headers"], "content-type": data["media_type"]}
            self.result = httpx.Response(200, headers=headers,
                                         content=base64.b64decode(data["body"]))

    def response(self) -> httpx.Response:
        """The result, once the stream has ended."""
        if self.result is None:
            raise ConnectionFailed("the event stream ended without a result")
        return self.result


def check(response: httpx.Response) -> httpx.Response:
    """The response, or its typed error."""
    if response.status_code >= 400:
        raise error_from_http(response.status_code, response.headers, response.content)
    return response


@contextlib.contextmanager
def translate(url: str) -> Iterator[None]:
    """httpx's transport errors -> :class:`ConnectionFailed` / :class:`ClientTimeout`."""
    try:
        yield
    except (httpx.ConnectError, httpx.ConnectTimeout, httpx.RemoteProtocolError,
            httpx.ReadError, httpx.WriteError) as error:
        raise ConnectionFailed(f"cannot reach {url}: {error or type(error).__name__}") from error
    except httpx.TimeoutException as error:
        raise ClientTimeout(f"no answer from {url} within the client's timeout "
                            f"({type(error).__name__})") from error
    except httpx.TransportError as error:
        raise ConnectionFailed(f"{url}: {error or type(error).__name__}") from error


def model_path(name: str) -> str:
    return "/v2/models/" + quote(name, safe="")


def model_name_from_server(metadata: Any) -> str:
    """The first model ``GET /v2`` lists, else :data:`DEFAULT_MODEL`."""
    models = metadata.get("models") if isinstance(metadata, dict) else None
    if isinstance(models, list) and models:
        first = models[0]
        return str(first.get("name") if isinstance(first, dict) else first)
    return DEFAULT_MODEL


def timeout_of(timeout: float | None, connect_timeout: float) -> httpx.Timeout:
    return httpx.Timeout(timeout, connect=connect_timeout)


class HttpTransport:
    """Blocking REST calls over one ``httpx.Client`` (connection pool, keep-alive)."""

    def __init__(self, url: str, *, timeout: float | None, connect_timeout: float,
                 headers: Mapping[str, str] | None, transport: Any = None,
                 verify: Verify = True) -> None:
        self.url = url.rstrip("/")
        self.http = httpx.Client(base_url=self.url, headers=dict(headers or {}),
                                 verify=http_verify(verify),
                                 timeout=timeout_of(timeout, connect_timeout),
                                 transport=transport)

    def send(self, call: Call) -> httpx.Response:
        with translate(self.url):
            return check(self.http.request(**call.kwargs()))

    def generate(self, source: Upload | Arrays, fmt: str | None,
                 options: Mapping[str, Any], progress: Any = None) -> Mesh:
        call = generate_request(source, fmt, options, stream=progress is not None)
        if progress is None:
            return mesh_from_response(self.send(call), fmt)
        reader = EventReader(progress)
        with translate(self.url), self.http.stream(**call.kwargs()) as response:
            if response.status_code >= 400:
                check(httpx.Response(response.status_code, headers=response.headers,
                                     content=response.read()))
            for line in response.iter_lines():
                reader.feed(line)
        return mesh_from_response(reader.response(), fmt)

    def repair(self, mesh: Upload, region: Mapping[str, Any], fmt: str | None,
               options: Mapping[str, Any], weld: bool = False) -> Mesh:
        call = repair_request(mesh, region, fmt, options, weld)
        return mesh_from_response(self.send(call), fmt)

    def health(self) -> Health:
        with translate(self.url):
            live = self.http.get("/v2/health/live").status_code == 200
            ready = self.http.get("/v2/health/ready").status_code == 200
        return Health(live, ready)

    def model_info(self, name: str | None) -> dict[str, Any]:
        if name is None:
            name = model_name_from_server(self.send(Call("GET", "/v2")).json())
        return self.send(Call("GET", model_path(name))).json()

    def close(self) -> None:
        self.http.close()


class AsyncHttpTransport:
    """Non-blocking REST calls over one ``httpx.AsyncClient``."""

    def __init__(self, url: str, *, timeout: float | None, connect_timeout: float,
                 headers: Mapping[str, str] | None, transport: Any = None,
                 verify: Verify = True) -> None:
        self.url = url.rstrip("/")
        self.http = httpx.AsyncClient(base_url=self.url, headers=dict(headers or {}),
                                      verify=http_verify(verify),
                                      timeout=timeout_of(timeout, connect_timeout),
                                      transport=transport)

    async def send(self, call: Call) -> httpx.Response:
        with translate(self.url):
            return check(await self.http.request(**call.kwargs()))

    async def generate(self, source: Upload | Arrays, fmt: str | None,
                       options: Mapping[str, Any], progress: Any = None) -> Mesh:
        call = generate_request(source, fmt, options, stream=progress is not None)
        if progress is None:
            return mesh_from_response(await self.send(call), fmt)
        reader = EventReader(progress)
        with translate(self.url):
            async with self.http.stream(**call.kwargs()) as response:
                if response.status_code >= 400:
                    check(httpx.Response(response.status_code, headers=response.headers,
                                         content=await response.aread()))
                async for line in response.aiter_lines():
                    reader.feed(line)
        return mesh_from_response(reader.response(), fmt)

    async def repair(self, mesh: Upload, region: Mapping[str, Any], fmt: str | None,
                     options: Mapping[str, Any], weld: bool = False) -> Mesh:
        call = repair_request(mesh, region, fmt, options, weld)
        return mesh_from_response(await self.send(call), fmt)

    async def health(self) -> Health:
        with translate(self.url):
            live = (await self.http.get("/v2/health/live")).status_code == 200
            ready = (await self.http.get("/v2/health/ready")).status_code == 200
        return Health(live, ready)

    async def model_info(self, name: str | None) -> dict[str, Any]:
        if name is None:
            name = model_name_from_server((await self.send(Call("GET", "/v2"))).json())
        return (await self.send(Call("GET", model_path(name)))).json()

    async def close(self) -> None:
        await self.http.aclose()
