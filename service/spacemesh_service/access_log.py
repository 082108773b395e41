"""Access logs and request ids: one JSON line per request, REST and gRPC alike.

Every request gets a request id: the client's ``X-Request-ID`` header (gRPC metadata
``x-request-id``) when it is sane (1 to 128 of ``A-Z a-z 0-9 . _ : -``), else a new
random one. It is echoed in the ``X-Request-ID`` response header (gRPC: trailing
metadata ``x-request-id``) and logged, at INFO, on the ``spacemesh.access`` logger::

    {"request_id": "...", "transport": "http", "method": "POST", "route": "/generate",
     "path": "/generate", "status": 200, "bytes": 5123, "ms": 412.3,
     "client": "10.0.0.7", "key": "3f9a0c1e22b7"}

``route`` is the route's template (``/v2/models/{name}``; null when nothing matched),
``status`` the HTTP status or the gRPC code's name, ``bytes`` the response body's size
(gRPC: the serialized messages), ``client`` the client address (see
:func:`spacemesh_service.security.client_address`) and ``key`` the API key's id (the
first hex digits of its SHA-256, never the key; null without keys).
"""

from __future__ import annotations

import json
import logging
import re
import time
import uuid
from collections.abc import Awaitable, Callable
from typing import Any

from spacemesh_service.security import asgi_header

#: The logger of the access lines.
ACCESS_LOGGER = "spacemesh.access"
#: The request id header (and, lower case, the gRPC metadata key).
REQUEST_ID_HEADER = "X-Request-ID"
_SANE_ID = re.compile(r"[A-Za-z0-9._:\-]{1,128}")

log = logging.getLogger(ACCESS_LOGGER)


def request_id(incoming: str | None) -> str:
    """The client's request id when sane, else a new one (32 hex digits)."""
    if incoming is not None and _SANE_ID.fullmatch(incoming):
        return incoming
    return uuid.uuid4().hex


def log_request(**fields: Any) -> None:
    """Log one access line (the fields as JSON, in the order given)."""
    if log.isEnabledFor(logging.INFO):
        log.info(json.dumps(fields, separators=(", ", ": "), default=str))


class RestAccessLog:
    """ASGI middleware (outermost): the request id and the access line of each request.

    The id is left in ``scope["state"]["request_id"]``; the client address and key id
    are read from ``scope["state"]["caller"]``
    (:class:`spacemesh_service.security.RestGuard`, inside this one).
    """

    def __init__(self, app: Callable[..., Awaitable[None]]) -> None:
        self.app = app

    async def __call__(self, scope: dict[str, Any], receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        rid = request_id(asgi_header(scope, b"x-request-id"))
        scope.setdefault("state", {})["request_id"] = rid
        started = time.perf_counter()
        status, size = 500, 0

        async def send_and_count(message: dict[str, Any]) -> None:
            nonlocal status, size
            if message["type"] == "http.response.start":
                status = message["status"]
                message = {**message, "headers": [*message.get("headers", ()),
                                                  (b"x-request-id", rid.encode())]}
            elif message["type"] == "http.response.body":
                size += len(message.get("body", b""))
            await send(message)

        try:
            await self.app(scope, receive, send_and_count)
        finally:
            caller = scope["state"].get("caller")
            client = scope.get("client")
            route = getattr(scope.get("route"), "path", None)
            log_request(request_id=rid, transport="http", method=scope.get("method"),
                        route=route, path=scope.get("path"), status=status, bytes=size,
                        ms=round((time.perf_counter() - started) * 1000, 1),
                        client=caller.address if caller else (client[0] if client else None),
                        key=caller.key if caller else None)
