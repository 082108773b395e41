"""Connections: timeouts on headers, bodies and idle connections, and TLS, for both ports.

REST (uvicorn):

* **headers**: uvicorn's h11 protocol closes an idle keep-alive connection
  (``timeout_keep_alive``) but has no limit on a connection that never completes its
  request headers: a client that connects and sends nothing, or sends half a header
  line, holds the connection forever. :func:`http_protocol` subclasses it with a timer
  that runs whenever the server waits for a request's headers (from the connection's
  start, and from the first byte of each further request) and closes the connection when
  they are not complete within ``header_timeout_s``. h11 bounds their size (16 KiB).
* **body**: :class:`BodyTimeout` (ASGI) gives the whole body ``body_timeout_s`` from the
  request's start; a body that trickles in slower gets 408 ``request-timeout`` and the
  connection is closed.
* **idle**: ``idle_timeout_s`` is uvicorn's ``timeout_keep_alive``.

gRPC: the same ``header_timeout_s`` bounds the connection handshake
(``grpc.server_handshake_timeout_ms``); idle connections are closed after
``grpc_idle_timeout_s`` (``grpc.max_connection_idle_ms``), all connections after
``grpc_max_connection_age_s`` when set (``grpc.max_connection_age_ms``, with the drain
timeout as grace), and dead peers are found by keepalive pings (``grpc.keepalive_*``).
A message is received whole before a handler sees it; its size is bounded by the upload
limit. gRPC has no limit on how slowly one message may arrive: the connection's age
(``grpc_max_connection_age_s``, 300 s by default) bounds that time.

TLS: one certificate and key (``--tls-cert``/``--tls-key``, both or neither) serve both
ports; :func:`load_tls` checks that they are readable and belong together at start-up.
"""

from __future__ import annotations

import asyncio
import logging
import ssl
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from spacemesh_service import problems as P
from spacemesh_service.problems import Problem
from spacemesh_service.security import ConfigError

log = logging.getLogger("spacemesh.service")


# ---------------------------------------------------------------------- headers
class _HeaderTimeoutProtocol(H11Protocol):
    """uvicorn's h11 protocol, closing connections whose headers do not arrive in time."""

    header_timeout: float = 10.0

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        self._header_timer: asyncio.TimerHandle | None = None
        super().connection_made(transport)
        self._watch_headers()

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        self._watch_headers()

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_header_timer()
        super().connection_lost(exc)

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._stop_header_timer()  # idle until the next byte: the keep-alive timeout's

    def _waiting_for_headers(self) -> bool:
        return self.conn.their_state is h11.IDLE and (
            self.cycle is None or self.cycle.response_complete)

    def _watch_headers(self) -> None:
        if self.transport.is_closing() or not self._waiting_for_headers():
            self._stop_header_timer()
        elif self._header_timer is None and self.timeout_keep_alive_task is None:
            self._header_timer = self.loop.call_later(self.header_timeout, self._headers_late)

    def _stop_header_timer(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _headers_late(self) -> None:
        self._header_timer = None
        if self._waiting_for_headers() and not self.transport.is_closing():
            log.debug("closing a connection that sent no complete headers in %.1f s",
                      self.header_timeout)
            self.transport.close()


def http_protocol(header_timeout: float) -> type[asyncio.Protocol]:
    """uvicorn's ``http`` protocol class, with a header timeout of ``header_timeout`` s."""
    return type("HeaderTimeoutProtocol", (_HeaderTimeoutProtocol,),
                {"header_timeout": header_timeout})


# ---------------------------------------------------------------------- bodies
class BodyTimedOut(Problem):
    """408 ``request-timeout``; the connection is closed after it (the rest of the body
    is never read)."""

    def __init__(self, seconds: float) -> None:
        super().__init__(P.REQUEST_TIMEOUT, f"the request body did not arrive within "
                         f"{seconds:g} s", limit_s=seconds)

    def headers(self) -> dict[str, str]:
        return {**super().headers(), "Connection": "close"}


class BodyTimeout:
    """ASGI middleware: a request's body must arrive within ``seconds`` of its start.

    Each read of the body waits at most the time left; when it runs out the read raises
    :class:`BodyTimedOut` (a :class:`Problem`, answered as 408 by the app). Reads after
    the body's end (waiting for a disconnect) are not limited.

    Parameters
    ----------
    app : ASGI app
    seconds : float
    """

    def __init__(self, app: Callable[..., Awaitable[None]], seconds: float) -> None:
        self.app = app
        self.seconds = seconds

    async def __call__(self, scope: dict[str, Any], receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.seconds
        complete = False

        async def timed_receive() -> dict[str, Any]:
            nonlocal complete
            if complete:
                return await receive()
            try:
                message = await asyncio.wait_for(receive(), max(0.0, deadline - loop.time()))
            except asyncio.TimeoutError:
                raise BodyTimedOut(self.seconds) from None
            if message["type"] != "http.request" or not message.get("more_body", False):
                complete = True
            return message

        await self.app(scope, timed_receive, send)


# ---------------------------------------------------------------------- TLS
@dataclass(frozen=True)
class Tls:
    """A certificate chain and its key (PEM), for both servers."""

    cert: Path
    key: Path

    def chain(self) -> bytes:
        """The certificate chain's PEM bytes."""
        return self.cert.read_bytes()

    def private_key(self) -> bytes:
        """The key's PEM bytes."""
        return self.key.read_bytes()


def load_tls(cert: Path | None, key: Path | None) -> Tls | None:
    """The TLS files, checked, or None without them.

    Raises
    ------
    ConfigError
        Only one of the two, a file unreadable, or a key that is not the certificate's.
    """
    if cert is None and key is None:
        return None
    if cert is None or key is None:
        raise ConfigError("--tls-cert and --tls-key go together: give both or neither")
    try:
        ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(cert, key)
    except FileNotFoundError as error:
        raise ConfigError(f"TLS: no such file {error.filename}") from None
    except (OSError, ssl.SSLError) as error:
        reason = getattr(error, "reason", None) or getattr(error, "strerror", None) or error
        raise ConfigError(f"TLS: cannot use the certificate {cert} with the key {key}: "
                          f"{reason}") from None
    return Tls(Path(cert), Path(key))


# ---------------------------------------------------------------------- servers
def uvicorn_options(settings: Any, tls: Tls | None) -> dict[str, Any]:
    """The ``uvicorn.Config`` keywords of the timeouts and TLS."""
    options: dict[str, Any] = {
        "http": http_protocol(settings.header_timeout_s),
        "timeout_keep_alive": settings.idle_timeout_s,
        # X-Forwarded-For is read by spacemesh_service.security, from --trusted-proxies
        # only (uvicorn's own reading trusts 127.0.0.1 by default)
        "proxy_headers": False,
    }
    if tls is not None:
        options.update(ssl_certfile=str(tls.cert), ssl_keyfile=str(tls.key))
    return options


def _ms(seconds: float) -> int:
    return max(1, round(seconds * 1000))


def grpc_options(settings: Any) -> list[tuple[str, int]]:
    """The gRPC server's connection options (timeouts and keepalive)."""
    options = [
        ("grpc.server_handshake_timeout_ms", _ms(settings.header_timeout_s)),
        ("grpc.max_connection_idle_ms", _ms(settings.grpc_idle_timeout_s)),
        ("grpc.keepalive_time_ms", _ms(settings.grpc_keepalive_s)),
        ("grpc.keepalive_timeout_ms", _ms(settings.grpc_keepalive_timeout_s)),
        ("grpc.keepalive_permit_without_calls", 1),
    ]
    if settings.grpc_max_connection_age_s > 0:
        options += [("grpc.max_connection_age_ms", _ms(settings.grpc_max_connection_age_s)),
                    ("grpc.max_connection_age_grace_ms", _ms(settings.drain_timeout_s))]
    return options


def grpc_credentials(tls: Tls | None) -> Any:
    """``grpc.ssl_server_credentials`` of the certificate, or None (plaintext)."""
    if tls is None:
        return None
    import grpc

    return grpc.ssl_server_credentials([(tls.private_key(), tls.chain())])
