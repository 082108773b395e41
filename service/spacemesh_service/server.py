"""One process, one event loop: REST (uvicorn) and gRPC over one shared engine.

Start-up: both servers listen first (``/v2/health/live`` answers at once), then the
model loads and warms up in the background; ``/v2/health/ready`` and grpc.health.v1
turn ready after that. A model that fails to load ends the process with exit code 1.

SIGTERM (or SIGINT) drains: readiness turns false, new requests get a 503
``shutting-down`` with Retry-After (gRPC UNAVAILABLE) while requests already received
(queued or running) finish, for at least ``drain_notice_s`` and at most
``drain_timeout_s``; then both servers close and the process exits 0. A second SIGINT
exits at once.

Protection and connections (:mod:`spacemesh_service.security`,
:mod:`spacemesh_service.connections`, :mod:`spacemesh_service.access_log`): one
:class:`~spacemesh_service.security.Guard` (API keys, rate limits) and one TLS
certificate serve both ports; settings that cannot be used (an empty key file, a key that
is not the certificate's) stop the start-up with a one-line message and exit code 2.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import sys
import threading
import time
from collections.abc import Iterator

import uvicorn

from spacemesh.runtime.pipeline import MeshGenerator
from spacemesh_service.access_log import ACCESS_LOGGER
from spacemesh_service.app import create_app
from spacemesh_service.connections import load_tls, uvicorn_options
from spacemesh_service.engine import Engine
from spacemesh_service.grpc_server import GrpcServer
from spacemesh_service.security import ConfigError, Guard
from spacemesh_service.settings import Settings

log = logging.getLogger("spacemesh.service")


class _Uvicorn(uvicorn.Server):
    """uvicorn without its own signal handlers (:class:`SpaceMeshServer` owns them)."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


class SpaceMeshServer:
    """REST and gRPC servers sharing one :class:`Engine`.

    Parameters
    ----------
    settings : Settings
    generator : MeshGenerator, optional
        An already loaded model (default: load ``settings.model``).

    Attributes
    ----------
    http_port, grpc_port : int or None
        The bound ports, once :attr:`listening` is set.
    listening : threading.Event
        Set when both servers accept connections.
    exit_code : int

    Raises
    ------
    ConfigError
        A protection or TLS setting cannot be used (the message says why).
    """

    def __init__(self, settings: Settings, *, generator: MeshGenerator | None = None) -> None:
        self.settings = settings
        self.guard = Guard.from_settings(settings)
        self.tls = load_tls(settings.tls_cert, settings.tls_key)
        self.engine = Engine(settings, generator=generator)
        self.app = create_app(settings, engine=self.engine, guard=self.guard)
        self.http_port: int | None = None
        self.grpc_port: int | None = None
        self.listening = threading.Event()
        self.exit_code = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stopping: asyncio.Task | None = None
        self._uvicorn: _Uvicorn | None = None
        self._grpc: GrpcServer | None = None

    async def serve(self, *, handle_signals: bool = True) -> int:
        """Run until shut down; returns the exit code.

        Parameters
        ----------
        handle_signals : bool
            Drain on SIGTERM/SIGINT (only possible in the main thread).
        """
        s = self.settings
        self._loop = asyncio.get_running_loop()
        if s.grpc:
            self._grpc = GrpcServer(self.engine, guard=self.guard, tls=self.tls)
            self.grpc_port = await self._grpc.start(s.grpc_port)
        config = uvicorn.Config(self.app, host=s.host, port=s.port, log_level=s.log_level,
                                lifespan="on", access_log=False,
                                timeout_graceful_shutdown=max(1, int(s.drain_timeout_s)),
                                **uvicorn_options(s, self.tls))
        self._uvicorn = _Uvicorn(config)
        http = asyncio.ensure_future(self._uvicorn.serve())
        while not self._uvicorn.started:
            if http.done():  # could not bind (uvicorn logged why)
                await self._stop_grpc(0)
                http.result()
                return 1
            await asyncio.sleep(0.01)
        self.http_port = self._uvicorn.servers[0].sockets[0].getsockname()[1]
        if handle_signals:
            self._loop.add_signal_handler(signal.SIGTERM, self.shutdown)
            self._loop.add_signal_handler(signal.SIGINT, self._interrupt)
        log.info("listening: rest=%s://%s:%s grpc=%s", self.scheme, s.host, self.http_port,
                 f"{s.host}:{self.grpc_port}" if self.grpc_port else "off")
        self.listening.set()
        try:
            await self.engine.start()
        except Exception as error:
            log.error("spacemesh serve: cannot load the model: %s", error)
            self.exit_code = 1
            self.shutdown()
        else:
            if self._grpc is not None and self.engine.ready:
                await self._grpc.set_serving()
        await http
        if self._stopping is not None:
            await self._stopping
        if handle_signals:
            for sig in (signal.SIGTERM, signal.SIGINT):
                self._loop.remove_signal_handler(sig)
        return self.exit_code

    @property
    def scheme(self) -> str:
        """``https`` with TLS, else ``http``."""
        return "https" if self.tls is not None else "http"

    def shutdown(self) -> None:
        """Start draining (call on the server's loop; see :meth:`shutdown_threadsafe`)."""
        if self._stopping is None and self._loop is not None:
            self._stopping = self._loop.create_task(self._drain())

    def shutdown_threadsafe(self) -> None:
        """:meth:`shutdown` from another thread."""
        if self._loop is not None:
            self._loop.call_soon_threadsafe(self.shutdown)

    def _interrupt(self) -> None:
        if self._stopping is not None and self._uvicorn is not None:
            self._uvicorn.force_exit = True  # second Ctrl-C
        self.shutdown()

    async def _stop_grpc(self, grace: float) -> None:
        if self._grpc is not None:
            await self._grpc.stop(grace)

    async def _drain(self) -> None:
        """Refuse new work with 503 ``shutting-down`` (gRPC UNAVAILABLE) while the work
        already received finishes, for at least ``drain_notice_s`` (so that a balancer
        that still sends traffic gets an answer it can retry elsewhere, not a refused
        connection) and at most ``drain_timeout_s``; then close both servers."""
        grace = self.settings.drain_timeout_s
        log.info("draining (up to %.0f s)", grace)
        self.engine.begin_drain()  # readiness 503, new requests 503 shutting-down
        if self._grpc is not None:
            await self._grpc.set_not_serving()
        notice = asyncio.ensure_future(asyncio.sleep(min(self.settings.drain_notice_s, grace)))
        drained = await self.engine.stop(grace)
        await notice
        if self._uvicorn is not None:
            self._uvicorn.should_exit = True  # stop accepting, finish open responses
        await self._stop_grpc(0)  # no call is left running: the engine has drained
        if not drained:
            log.warning("drain timeout: some requests were cancelled")


class BackgroundServer:
    """A :class:`SpaceMeshServer` in a daemon thread (benchmarks, tests, notebooks).

    Parameters
    ----------
    settings : Settings
    generator : MeshGenerator, optional

    Examples
    --------
    >>> server = BackgroundServer(Settings(port=0, grpc_port=0)).start()  # doctest: +SKIP
    >>> httpx.get(server.url + "/v2/health/ready")  # doctest: +SKIP
    >>> server.stop()  # doctest: +SKIP
    """

    def __init__(self, settings: Settings, generator: MeshGenerator | None = None) -> None:
        self.server = SpaceMeshServer(settings, generator=generator)
        self.thread = threading.Thread(target=self._run, daemon=True, name="spacemesh-server")
        self.exit_code: int | None = None

    def _run(self) -> None:
        self.exit_code = asyncio.run(self.server.serve(handle_signals=False))

    def start(self, wait_ready: bool = True, timeout: float = 120.0) -> BackgroundServer:
        """Start, and wait until listening (and ready, unless ``wait_ready`` is False)."""
        self.thread.start()
        deadline = time.monotonic() + timeout
        while not self.server.listening.wait(0.05):
            if not self.thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError("the server did not start")
        while wait_ready and not self.server.engine.ready:
            if self.server.engine.state == "failed" or time.monotonic() > deadline:
                raise RuntimeError(f"the model did not become ready: {self.server.engine.error}")
            time.sleep(0.02)
        return self

    @property
    def url(self) -> str:
        """``http(s)://host:port`` of the REST server."""
        return f"{self.server.scheme}://{self.server.settings.host}:{self.server.http_port}"

    @property
    def grpc_target(self) -> str:
        """``host:port`` of the gRPC server."""
        return f"{self.server.settings.host}:{self.server.grpc_port}"

    def stop(self, timeout: float = 60.0) -> None:
        """Drain and wait for the thread to end."""
        self.server.shutdown_threadsafe()
        self.thread.join(timeout)


def configure_logging(level: str, access_log: bool = True) -> None:
    """Log the service's messages to stderr at ``level``, and the access lines
    (:mod:`spacemesh_service.access_log`, JSON) to stdout at INFO unless ``access_log``
    is False (they do not depend on ``level``)."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s:     %(message)s"))
    logger = logging.getLogger("spacemesh.service")
    logger.handlers[:] = [handler]
    logger.setLevel(level.upper())
    logger.propagate = False
    access = logging.StreamHandler(sys.stdout)
    access.setFormatter(logging.Formatter("%(message)s"))
    access_logger = logging.getLogger(ACCESS_LOGGER)
    access_logger.handlers[:] = [access]
    access_logger.setLevel(logging.INFO if access_log else logging.CRITICAL + 1)
    access_logger.propagate = False


def run(settings: Settings) -> int:
    """Serve until SIGTERM; returns the exit code (``spacemesh serve`` calls this): 2 with
    a one-line message when a protection or TLS setting cannot be used."""
    configure_logging(settings.log_level, settings.access_log)
    try:
        server = SpaceMeshServer(settings)
    except ConfigError as error:
        print(f"spacemesh serve: {error}", file=sys.stderr)
        return 2
    return asyncio.run(server.serve())
