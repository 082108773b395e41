"""``Client`` and ``AsyncClient``: the SpaceMesh service from Python.

>>> from spacemesh_client import Client
>>> with Client("http://localhost:8000") as client:  # doctest: +SKIP
...     mesh = client.generate("points.ply", seed=7)
...     mesh.save("mesh.glb")
...     print(mesh.stats.faces, mesh.stats.face_degrees)

The URL picks the transport: ``http(s)://`` speaks REST, ``grpc(s)://`` speaks gRPC
(``proto/spacemesh.proto``); the methods, results and exceptions are the same. Every call
is retried by the client's :class:`~spacemesh_client.retry.RetryPolicy` on connection
errors, 503 and 429, waiting at least the server's ``Retry-After``.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable, Mapping
from typing import Any, TypeVar
from urllib.parse import urlsplit

from spacemesh_client._http import AsyncHttpTransport, Call, Health, HttpTransport
from spacemesh_client._inputs import (
    MeshLike,
    PointsLike,
    RegionLike,
    mesh_input,
    points_input,
    region_input,
)
from spacemesh_client.errors import ConnectionFailed, SpaceMeshError
from spacemesh_client.mesh import Mesh
from spacemesh_client.options import chosen
from spacemesh_client.progress import ProgressFn, StageFn, reporter
from spacemesh_client.retry import DEFAULT_RETRY, RetryPolicy
from spacemesh_client.security import Verify, auth_headers

#: Where a client connects unless told otherwise (``SPACEMESH_URL`` in the CLI).
DEFAULT_URL = "http://localhost:8000"
#: The output format a client asks for unless told otherwise: binary PLY keeps polygon
#: faces and exact coordinates (the server's own default is GLB).
DEFAULT_FORMAT = "ply"

T = TypeVar("T")


def _is_grpc(url: str) -> bool:
    return urlsplit(url).scheme in ("grpc", "grpcs")


def _check_url(url: str) -> str:
    if urlsplit(url).scheme not in ("http", "https", "grpc", "grpcs"):
        raise ValueError(f"unsupported URL {url!r}: use http(s)://host:port (REST) or "
                         "grpc(s)://host:port (gRPC)")
    return url


class _Options:
    """What both clients keep: URL, timeouts and retry policy."""

    def __init__(self, url: str, timeout: float | None, connect_timeout: float,
                 retry: RetryPolicy | None, headers: Mapping[str, str] | None,
                 api_key: str | None = None, verify: Verify = True) -> None:
        self.url = _check_url(url)
        self.timeout = timeout
        self.connect_timeout = connect_timeout
        self.retry = retry or DEFAULT_RETRY
        self.headers = auth_headers(headers, api_key)
        self.verify = verify

    @property
    def transport_name(self) -> str:
        return "grpc" if _is_grpc(self.url) else "rest"

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.url!r})"


class Client(_Options):
    """A blocking client.

    Parameters
    ----------
    url : str
        ``http://host:8000`` (REST) or ``grpc://host:8001`` (gRPC); ``https``/``grpcs``
        for TLS.
    timeout : float or None
        Seconds one attempt may take (None: no limit). Generation of a large cloud takes
        seconds to minutes on a CPU; the server has its own limit (504 ``timeout``).
    connect_timeout : float
        Seconds to open a connection (REST).
    retry : RetryPolicy, optional
        Default :data:`~spacemesh_client.retry.DEFAULT_RETRY` (5 attempts);
        ``RetryPolicy.never()`` to fail at once.
    headers : mapping, optional
        Sent with every request (REST headers, gRPC metadata), e.g. an authorization.
    transport : httpx.BaseTransport, optional
        An httpx transport for REST (tests, proxies); ignored for gRPC.
    api_key : str, optional
        Sent as ``Authorization: Bearer KEY`` (REST header, gRPC metadata); default
        ``$SPACEMESH_API_KEY`` (``""``: none). A missing or wrong key raises
        :class:`~spacemesh_client.errors.Unauthorized`.
    verify : bool or path
        How ``https``/``grpcs`` check the server's certificate: True (the system's CAs),
        the path of a PEM file of CA certificates (e.g. a self-signed server
        certificate), or False (REST only: no check).
    """

    def __init__(self, url: str = DEFAULT_URL, *, timeout: float | None = 300.0,
                 connect_timeout: float = 10.0, retry: RetryPolicy | None = None,
                 headers: Mapping[str, str] | None = None, transport: Any = None,
                 api_key: str | None = None, verify: Verify = True) -> None:
        super().__init__(url, timeout, connect_timeout, retry, headers, api_key, verify)
        if _is_grpc(url):
            from spacemesh_client.grpc_transport import GrpcTransport

            self._transport: Any = GrpcTransport(url, timeout=timeout, metadata=self.headers,
                                                 verify=verify)
        else:
            self._transport = HttpTransport(url, timeout=timeout,
                                            connect_timeout=connect_timeout,
                                            headers=self.headers, transport=transport,
                                            verify=verify)

    def _retrying(self, attempt_once: Callable[[], T]) -> T:
        attempt = 1
        while True:
            try:
                return attempt_once()
            except SpaceMeshError as error:
                wait = self.retry.delay(attempt, error)
                if wait is None:
                    raise
            time.sleep(wait)
            attempt += 1

    def generate(self, points: PointsLike, *, normals: Any = None,
                 format: str | None = DEFAULT_FORMAT, seed: int | None = None,
                 steps: int | None = None, sampler: str | None = None,
                 start: str | None = None, start_time: float | None = None,
                 target_vertices: int | None = None, tolerance: float | None = None,
                 samples: int | None = None,
                 raw: bool | None = None, surface: str | None = None,
                 face_type: str | None = None, filename: str | None = None,
                 progress: ProgressFn | None = None, stage: StageFn | None = None) -> Mesh:
        """Point cloud in, oriented manifold polygon mesh out.

        Parameters
        ----------
        points : array-like, path, bytes or trimesh object
            (P, 3) numbers (or (P, 6) with normals); a point-cloud file (PLY, XYZ, PTS,
            TXT, NPY, NPZ, LAS, LAZ, OBJ, OFF, STL, GLB, glTF) or its bytes; or a
            ``trimesh.PointCloud`` / ``trimesh.Trimesh`` (its vertices).
        normals : array-like, optional
            (P, 3) normals for points given as numbers.
        format : str or None
            ``ply`` (default here: polygons and exact coordinates), ``glb``, ``gltf``,
            ``obj``, ``off`` or ``json``; None for the server's default (GLB).
        seed : int, optional
            The same input, seed and options give the same mesh; the server picks one
            when None (and reports it as ``Mesh.seed``).
        steps : int, optional
            Sampler steps (the model's default when None).
        sampler : {"ddim", "ddpm"}, optional
            The model's default when None.
        start : {"noise", "points"}, optional
            Where the vertices start: ``noise`` (the paper's diffusion) or ``points``
            (chosen on the input by farthest-point sampling, noised to ``start_time``
            and denoised from there); the model's default when None.
        start_time : float, optional
            With ``start="points"`` only: the fraction of the diffusion (0..1) where it
            begins; 0 uses the chosen points as they are.
        target_vertices : int, optional
            Vertices of the mesh (within 10%), 4..10,000; needs ``start="points"``.
        tolerance : float, optional
            The smallest mesh whose mean distance from the points to the mesh is at most
            this fraction of the points' bounding-box diagonal (1e-4..0.5); not with
            ``target_vertices``. ``Mesh.stats.fit`` reports ``tolerance_met``.
        samples : int, optional
            Generate seeds ``seed .. seed + samples - 1`` (1..16) and return the mesh
            that fits the points best (``Mesh.seed`` is its seed, ``Mesh.sample_scores``
            every seed's score).
        raw : bool, optional
            The networks' mesh without the geometry stage.
        surface : {"auto", "closed", "open"}, optional
            ``closed``: watertight; ``open``: trimmed to where the points are (a scan
            seen from some sides only); ``auto`` (the server's default): open when the
            points leave a large part of the closed mesh unsupported.
            ``Mesh.stats.fit["open_surface"]`` says what was made.
        face_type : {"triangles", "polygons"}, optional
            ``polygons``: flat regions without interior vertices (fewer vertices than
            asked for), merged into planar polygons
            (``Mesh.stats.fit["face_planarity"]`` is the worst corner's distance from
            its plane, a fraction of the diagonal; GLB and glTF hold triangles only).
        filename : str, optional
            Name sent with bytes (its extension picks the format).
        progress : callable, optional
            ``progress(step, total)`` after each diffusion step (gRPC
            ``GenerateStream``; over REST ``POST /generate/stream``, Server-Sent Events).
        stage : callable, optional
            ``stage(name, done, total)`` for each progress event of the stream: as each
            stage begins (``queued``, ``encoder``, ``sampler``, ``connectivity``,
            ``decode``, ``geometry``, ``report``, ``encode_output``; with ``tolerance``,
            ``tolerance`` before each try of the search, which then runs the stages
            again) and per sampler step (``sampler``), over either transport.

        Returns
        -------
        Mesh
            ``Mesh.stats.fit`` says how well it fits the points, ``Mesh.options`` which
            options the server used.

        Raises
        ------
        SpaceMeshError
            A subclass per problem type (:mod:`spacemesh_client.errors`); an option out
            of range raises :class:`~spacemesh_client.errors.InvalidOption` (422).
        """
        source = points_input(points, normals, filename)
        options = chosen(seed=seed, steps=steps, sampler=sampler, start=start,
                         start_time=start_time, target_vertices=target_vertices,
                         tolerance=tolerance, samples=samples, raw=raw,
                         surface=surface, face_type=face_type)
        return self._retrying(
            lambda: self._transport.generate(source, format, options,
                                             reporter(progress, stage)))

    def repair(self, mesh: MeshLike, region: RegionLike = None, *,
               format: str | None = DEFAULT_FORMAT,
               seed: int | None = None, steps: int | None = None,
               sampler: str | None = None, filename: str | None = None,
               weld: bool = False, auto: str | None = None,
               max_growth: float | None = None) -> Mesh:
        """Regenerate a region of a mesh; faces outside it stay unchanged.

        Parameters
        ----------
        mesh : path, bytes, Mesh or trimesh.Trimesh
            A mesh file the server reads (OBJ, OFF, PLY, STL, GLB, glTF), its bytes, a
            :class:`Mesh` (a ``json`` one is sent as PLY) or a trimesh object (sent as
            PLY). Face and vertex indices refer to this file's order.
        region : dict or list of int
            ``{"faces": [...]}``, ``{"vertices": [...]}``,
            ``{"sphere": {"center": [x, y, z], "radius": r}}``,
            ``{"box": {"min": [x, y, z], "max": [x, y, z]}}`` (mesh coordinates),
            ``{"auto": "holes" | "defects" | "all"}``, or face indices; the same over
            REST and gRPC. Omitted when ``auto`` is given.
        format, seed, steps, sampler, filename
            As for :meth:`generate`.
        weld : bool
            Ask the server to merge vertices at exactly equal positions before the repair
            (meshes split at UV seams or hard edges, as GLB files often are, look open
            otherwise and are refused with ``DefectsOutsideRegion``). Region vertex
            indices stay this file's; the result is the welded mesh repaired, so its
            vertex indices differ from the file's (``repair["welded_vertices"]`` says how
            many vertices were merged away).
        auto : {"holes", "defects", "all"}, optional
            Let the server find the regions: every hole (boundary loop) with the ring of
            faces around it, every defect (non-manifold edges and vertices, degenerate
            faces) with its neighbourhood, or both; each is repaired by a pass of its
            own and ``repair["findings"]`` says what was found and done. Not with
            ``region``.
        max_growth : float, optional
            Largest share (0 to 1) of the mesh's faces a region may grow to (the
            server's default 0.25); beyond it ``RegionGrowthExceeded``.

        Returns
        -------
        Mesh
            With :attr:`Mesh.repair`, what the repair did (faces re-generated, new
            vertices and faces, fallback, welded vertices...).

        Raises
        ------
        SpaceMeshError
            A region the server cannot use raises a
            :class:`~spacemesh_client.errors.RegionError` subclass (422):
            ``EmptyRegion``, ``WholeMeshRegion``, ``InvalidRegion``,
            ``DefectsOutsideRegion`` (``extra["defects"]``), ``RegionTooLarge``,
            ``RegionGrowthExceeded``, ``NonOrientable``.
        """
        upload = mesh_input(mesh, filename)
        shape = region_input(region, auto)
        options = chosen(seed=seed, steps=steps, sampler=sampler)
        if max_growth is not None:
            options["max_growth"] = float(max_growth)
        return self._retrying(
            lambda: self._transport.repair(upload, shape, format, options, weld))

    def health(self) -> Health:
        """Liveness and readiness (not retried; a refused connection raises
        :class:`~spacemesh_client.errors.ConnectionFailed`)."""
        return self._transport.health()

    def wait_until_ready(self, timeout: float = 60.0, interval: float = 0.5) -> Health:
        """Poll :meth:`health` until the server is ready.

        Raises
        ------
        TimeoutError
            Not ready within ``timeout`` seconds.
        """
        deadline = time.monotonic() + timeout
        last: Exception | Health | None = None
        while time.monotonic() < deadline:
            try:
                last = self.health()
                if last.ready:
                    return last
            except ConnectionFailed as error:
                last = error
            time.sleep(interval)
        raise TimeoutError(f"{self.url} not ready within {timeout} s (last: {last})")

    def model_info(self, name: str | None = None) -> dict[str, Any]:
        """``GET /v2/models/{name}``: versions, limits, formats, sampler, training card.

        Parameters
        ----------
        name : str, optional
            Default: the model the server lists, else ``spacemesh-small``.
        """
        return self._retrying(lambda: self._transport.model_info(name))

    def request(self, method: str, path: str, **kwargs: Any) -> Any:
        """A raw REST request (with retries and typed errors), e.g. ``GET /metrics``."""
        if _is_grpc(self.url):
            raise ValueError("raw requests need the REST transport")
        call = Call(method, path, **kwargs)
        return self._retrying(lambda: self._transport.send(call))

    def close(self) -> None:
        """Close the connections."""
        self._transport.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AsyncClient(_Options):
    """The same as :class:`Client`, for asyncio: every method is a coroutine.

    >>> async with AsyncClient("http://localhost:8000") as client:  # doctest: +SKIP
    ...     meshes = await asyncio.gather(*(client.generate(p) for p in clouds))
    """

    def __init__(self, url: str = DEFAULT_URL, *, timeout: float | None = 300.0,
                 connect_timeout: float = 10.0, retry: RetryPolicy | None = None,
                 headers: Mapping[str, str] | None = None, transport: Any = None,
                 api_key: str | None = None, verify: Verify = True) -> None:
        super().__init__(url, timeout, connect_timeout, retry, headers, api_key, verify)
        if _is_grpc(url):
            from spacemesh_client.grpc_transport import AsyncGrpcTransport

            self._transport: Any = AsyncGrpcTransport(url, timeout=timeout,
                                                      metadata=self.headers, verify=verify)
        else:
            self._transport = AsyncHttpTransport(url, timeout=timeout,
                                                 connect_timeout=connect_timeout,
                                                 headers=self.headers, transport=transport,
                                                 verify=verify)

    async def _retrying(self, attempt_once: Callable[[], Awaitable[T]]) -> T:
        attempt = 1
        while True:
            try:
                return await attempt_once()
            except SpaceMeshError as error:
                wait = self.retry.delay(attempt, error)
                if wait is None:
                    raise
            await asyncio.sleep(wait)
            attempt += 1

    async def generate(self, points: PointsLike, *, normals: Any = None,
                       format: str | None = DEFAULT_FORMAT, seed: int | None = None,
                       steps: int | None = None, sampler: str | None = None,
                       start: str | None = None, start_time: float | None = None,
                       target_vertices: int | None = None, tolerance: float | None = None,
                       samples: int | None = None,
                       raw: bool | None = None, surface: str | None = None,
                       face_type: str | None = None, filename: str | None = None,
                       progress: ProgressFn | None = None,
                       stage: StageFn | None = None) -> Mesh:
        """See :meth:`Client.generate`."""
        source = points_input(points, normals, filename)
        options = chosen(seed=seed, steps=steps, sampler=sampler, start=start,
                         start_time=start_time, target_vertices=target_vertices,
                         tolerance=tolerance, samples=samples, raw=raw,
                         surface=surface, face_type=face_type)
        return await self._retrying(
            lambda: self._transport.generate(source, format, options,
                                             reporter(progress, stage)))

    async def repair(self, mesh: MeshLike, region: RegionLike = None, *,
                     format: str | None = DEFAULT_FORMAT, seed: int | None = None,
                     steps: int | None = None, sampler: str | None = None,
                     filename: str | None = None, weld: bool = False,
                     auto: str | None = None, max_growth: float | None = None) -> Mesh:
        """See :meth:`Client.repair`."""
        upload = mesh_input(mesh, filename)
        shape = region_input(region, auto)
        options = chosen(seed=seed, steps=steps, sampler=sampler)
        if max_growth is not None:
            options["max_growth"] = float(max_growth)
        return await self._retrying(
            lambda: self._transport.repair(upload, shape, format, options, weld))

    async def health(self) -> Health:
        """See :meth:`Client.health`."""
        return await self._transport.health()

    async def wait_until_ready(self, timeout: float = 60.0, interval: float = 0.5) -> Health:
        """See :meth:`Client.wait_until_ready`."""
        deadline = time.monotonic() + timeout
        last: Exception | Health | None = None
        while time.monotonic() < deadline:
            try:
                last = await self.health()
                if last.ready:
                    return last
            except ConnectionFailed as error:
                last = error
            await asyncio.sleep(interval)
        raise TimeoutError(f"{self.url} not ready within {timeout} s (last: {last})")

    async def model_info(self, name: str | None = None) -> dict[str, Any]:
        """See :meth:`Client.model_info`."""
        return await self._retrying(lambda: self._transport.model_info(name))

    async def request(self, method: str, path: str, **kwargs: Any) -> Any:
        """See :meth:`Client.request`."""
        if _is_grpc(self.url):
            raise ValueError("raw requests need the REST transport")
        call = Call(method, path, **kwargs)
        return await self._retrying(lambda: self._transport.send(call))

    async def close(self) -> None:
        """Close the connections."""
        await self._transport.close()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()
