"""Typed exceptions: one class per problem type the service answers (RFC 9457).

The service answers every error as ``application/problem+json`` with a stable ``type``
URI, ``https://spacemesh.dev/problems/<slug>`` (over gRPC: a status code and the same
URI in the trailing metadata ``problem-type``). :func:`error_from_problem` turns such a
problem into the class registered for its slug in :data:`PROBLEM_TYPES`; an unknown type
becomes a plain :class:`SpaceMeshError`, so new server-side kinds never break a client.

The classes are grouped by what a caller can do about them::

    SpaceMeshError
    ├── InvalidRequest          fix the request (400, 404, 405, 413, 415, 422)
    │   ├── MalformedInput, InvalidParameter, InvalidOption, UnsupportedFormat,
    │   │   PayloadTooLarge, TooManyPoints, TooFewPoints, NonFinite, DegenerateGeometry,
    │   │   InvalidNormals, NormalsRequired, NotFound (ModelNotFound), MethodNotAllowed,
    │   │   Unauthorized (401: no or a wrong API key), RequestTimeout (408: the body
    │   │   arrived too slowly)
    │   └── RegionError         a repair region the server cannot use
    │       └── EmptyRegion, WholeMeshRegion, InvalidRegion, DefectsOutsideRegion,
    │           RegionTooLarge, RegionGrowthExceeded, NonOrientable
    ├── NoSurface               try another seed or more steps (422)
    ├── ServerError             InternalError, InvalidOutput, Unimplemented, Timeout
    ├── Unavailable             retried: QueueFull, NotReady, ShuttingDown (503),
    │                           RateLimited (429, the server's or a proxy's)
    └── TransportError          no answer: ConnectionFailed, ClientTimeout
"""

from __future__ import annotations

import email.utils
import json
import time
from collections.abc import Mapping
from typing import Any, ClassVar

#: Base of every problem type URI.
TYPE_BASE = "https://spacemesh.dev/problems/"
#: Media type of problem responses.
PROBLEM_MEDIA_TYPE = "application/problem+json"


class SpaceMeshError(Exception):
    """Any error of the SpaceMesh client; also what an unknown problem type becomes.

    Attributes
    ----------
    type : str or None
        The problem type URI (None for errors without an answer, e.g. no connection).
    title : str
    status : int or None
        The HTTP status (over gRPC: the status the REST API answers for the same error).
    detail : str
        What went wrong with this request.
    instance : str or None
    retry_after : float or None
        Seconds the server asked to wait (``Retry-After``).
    extra : dict
        The problem's extension members (``limit``, ``seed``, ``errors``...).
    """

    #: The slug this class stands for (None: a group or the base).
    slug: ClassVar[str | None] = None
    #: Whether :class:`~spacemesh_client.retry.RetryPolicy` may send the request again.
    retryable: ClassVar[bool] = False

    def __init__(
        self, detail: str, *, type: str | None = None, title: str = "", status: int | None = None,
        instance: str | None = None, retry_after: float | None = None,
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(detail)
        self.type = type if type is not None else (TYPE_BASE + self.slug if self.slug else None)
        self.title = title
        self.status = status
        self.detail = detail
        self.instance = instance
        self.retry_after = retry_after
        self.extra = dict(extra or {})

    def __str__(self) -> str:
        head = self.title or self.slug or type(self).__name__
        where = f" ({self.status})" if self.status else ""
        return f"{head}{where}: {self.detail}" if self.detail else f"{head}{where}"

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.detail!r}, type={self.type!r}, status={self.status})"


# ---------------------------------------------------------------------- groups
class InvalidRequest(SpaceMeshError):
    """The request cannot be served as sent; change it before sending it again."""


class RegionError(InvalidRequest):
    """A repair region the server cannot use (422)."""


class ServerError(SpaceMeshError):
    """The server failed (5xx other than 503)."""


class Unavailable(SpaceMeshError):
    """The server cannot take the request now (503); retried with backoff."""

    retryable = True


class TransportError(SpaceMeshError):
    """No answer came back (the request may not have reached the server)."""


# ---------------------------------------------------------------------- problem types
class MalformedInput(InvalidRequest):
    """The point cloud (or mesh) could not be read (400)."""

    slug = "malformed-input"


class InvalidParameter(InvalidRequest):
    """A request parameter that is not an option is invalid (400)."""

    slug = "invalid-parameter"


class InvalidOption(InvalidRequest):
    """An option is invalid (422): of the wrong type (``seed=1e3``), out of range, or not
    an option of the route; ``extra["option"]`` names it (``extra["unknown"]`` lists the
    names the route does not take)."""

    slug = "invalid-option"


class TooExpensive(InvalidRequest):
    """The request is estimated to cost more than the server's budget (422), before any
    work started; ``extra["option"]`` names the option to lower, ``extra["suggestion"]``
    (when present) a value of it that fits, ``extra["estimated_seconds"]``,
    ``extra["estimated_mb"]``, ``extra["budget_seconds"]`` and ``extra["budget_mb"]``
    the figures."""

    slug = "too-expensive"


class NotFound(InvalidRequest):
    """No such resource (404)."""

    slug = "not-found"


class ModelNotFound(NotFound):
    """No such model or version (404)."""

    slug = "model-not-found"


class MethodNotAllowed(InvalidRequest):
    """Method not allowed (405)."""

    slug = "method-not-allowed"


class Unauthorized(InvalidRequest):
    """No API key, or a wrong one (401; gRPC UNAUTHENTICATED): pass ``api_key=`` or set
    ``SPACEMESH_API_KEY``."""

    slug = "unauthorized"


class RequestTimeout(InvalidRequest):
    """The request body reached the server too slowly (408)."""

    slug = "request-timeout"


class PayloadTooLarge(InvalidRequest):
    """The request body is too large (413); ``extra["limit"]`` is the limit in bytes."""

    slug = "payload-too-large"


class TooManyPoints(InvalidRequest):
    """The point cloud has too many points (413); ``extra["limit"]``."""

    slug = "too-many-points"


class UnsupportedFormat(InvalidRequest):
    """Unsupported input format (415); ``extra["supported"]`` lists the readable ones."""

    slug = "unsupported-format"


class TooFewPoints(InvalidRequest):
    """The point cloud has too few points (422); ``extra["limit"]``."""

    slug = "too-few-points"


class NonFinite(InvalidRequest):
    """The point cloud has NaN or infinite values (422)."""

    slug = "non-finite"


class DegenerateGeometry(InvalidRequest):
    """Identical, collinear or coplanar points (422)."""

    slug = "degenerate-geometry"


class InvalidNormals(InvalidRequest):
    """The normals do not match the points (422)."""

    slug = "invalid-normals"


class NormalsRequired(InvalidRequest):
    """This model needs normals (422)."""

    slug = "normals-required"


class NoSurface(SpaceMeshError):
    """No surface for this input and seed (422); ``extra`` has the ``seed`` and ``steps``."""

    slug = "no-surface"


class EmptyRegion(RegionError):
    """The repair region selects no face."""

    slug = "empty-region"


class WholeMeshRegion(RegionError):
    """The repair region (after growing it) is the whole mesh."""

    slug = "whole-mesh-region"


class InvalidRegion(RegionError):
    """The repair region is malformed (unknown form, bad numbers, indices out of range)."""

    slug = "invalid-region"


class DefectsOutsideRegion(RegionError):
    """The mesh has defects the region does not cover (``extra["defects"]``)."""

    slug = "defects-outside-region"


class RegionTooLarge(RegionError):
    """The region's boundary alone needs more vertices than the model has."""

    slug = "region-too-large"


class RegionGrowthExceeded(RegionError):
    """The region would grow beyond ``max_growth`` of the mesh's faces (``extra["share"]``)."""

    slug = "region-growth-exceeded"


class NonOrientable(RegionError):
    """The mesh cannot be oriented (a Moebius strip): no closed oriented surface exists."""

    slug = "non-orientable"


class InternalError(ServerError):
    """Internal server error (500)."""

    slug = "internal-error"


class InvalidOutput(ServerError):
    """The generated mesh failed the server's validation (500)."""

    slug = "invalid-output"


class Unimplemented(ServerError):
    """Not implemented (501), e.g. repair on a server without it."""

    slug = "not-implemented"


class Timeout(ServerError):
    """The server gave up on the request after its time limit (504)."""

    slug = "timeout"


class QueueFull(Unavailable):
    """The server's queue is full (503)."""

    slug = "queue-full"


class NotReady(Unavailable):
    """The model is loading or warming up (503)."""

    slug = "not-ready"


class ShuttingDown(Unavailable):
    """The server is draining before it exits (503)."""

    slug = "shutting-down"


class RateLimited(Unavailable):
    """Too many requests (429; gRPC RESOURCE_EXHAUSTED): the server's rate limit, or a
    proxy's; retried after ``Retry-After``."""

    slug = "rate-limited"


class ConnectionFailed(TransportError):
    """The server could not be reached, or dropped the connection (retried)."""

    retryable = True


class ClientTimeout(TransportError):
    """No answer within the client's timeout (not retried: the server may still work)."""


def _subclasses(cls: type[SpaceMeshError]) -> list[type[SpaceMeshError]]:
    found = []
    for sub in cls.__subclasses__():
        found.append(sub)
        found.extend(_subclasses(sub))
    return found


#: Problem slug -> exception class.
PROBLEM_TYPES: dict[str, type[SpaceMeshError]] = {
    cls.slug: cls for cls in _subclasses(SpaceMeshError) if cls.slug
}
#: Classes for answers that are not problem+json (a proxy's own 429 or 503 page).
_BY_STATUS: dict[int, type[SpaceMeshError]] = {429: RateLimited, 503: Unavailable}


# ---------------------------------------------------------------------- parsing
def parse_retry_after(value: str | None, *, now: float | None = None) -> float | None:
    """Seconds from a ``Retry-After`` value (delay-seconds or an HTTP date).

    Parameters
    ----------
    value : str or None
    now : float, optional
        The current time (``time.time()``), for HTTP dates.

    Returns
    -------
    float or None
        None when absent or unreadable; never negative.
    """
    if value is None or not value.strip():
        return None
    text = value.strip()
    try:
        return max(0.0, float(text))
    except ValueError:
        pass
    try:
        when = email.utils.parsedate_to_datetime(text)
    except (TypeError, ValueError):
        return None
    return max(0.0, when.timestamp() - (time.time() if now is None else now))


def slug_of(type_uri: str | None) -> str | None:
    """``https://spacemesh.dev/problems/queue-full`` -> ``queue-full`` (None otherwise)."""
    if type_uri and type_uri.startswith(TYPE_BASE):
        return type_uri[len(TYPE_BASE):]
    return None


def error_from_problem(
    problem: Mapping[str, Any], *, status: int | None = None, retry_after: float | None = None
) -> SpaceMeshError:
    """The exception for a problem object.

    Parameters
    ----------
    problem : mapping
        ``type``, ``title``, ``status``, ``detail``, ``instance`` and extension members.
    status : int, optional
        The response status (used when the problem has none).
    retry_after : float, optional

    Returns
    -------
    SpaceMeshError
        The class of :data:`PROBLEM_TYPES` for the type, else by status (429, 503), else
        :class:`SpaceMeshError`.
    """
    known = {"type", "title", "status", "detail", "instance"}
    type_uri = problem.get("type")
    type_uri = type_uri if isinstance(type_uri, str) else None
    code = problem.get("status") if isinstance(problem.get("status"), int) else status
    cls = PROBLEM_TYPES.get(slug_of(type_uri) or "") or _BY_STATUS.get(code or 0, SpaceMeshError)
    return cls(
        str(problem.get("detail") or ""), type=type_uri or "about:blank",
        title=str(problem.get("title") or ""), status=code,
        instance=problem.get("instance") if isinstance(problem.get("instance"), str) else None,
        retry_after=retry_after, extra={k: v for k, v in problem.items() if k not in known},
    )


def error_from_http(status: int, headers: Mapping[str, str], content: bytes) -> SpaceMeshError:
    """The exception for an HTTP error response (problem+json or anything else).

    Parameters
    ----------
    status : int
    headers : mapping
        Case-insensitive (``httpx.Headers``).
    content : bytes

    Returns
    -------
    SpaceMeshError
    """
    lower = {k.lower(): v for k, v in headers.items()}
    retry_after = parse_retry_after(lower.get("retry-after"))
    problem: Any = None
    if content:
        try:
            problem = json.loads(content)
        except (ValueError, UnicodeDecodeError):
            problem = None
    if not isinstance(problem, dict) or ("type" not in problem and "title" not in problem):
        text = content.decode("utf-8", "replace").strip() if content else ""
        problem = {"title": f"HTTP {status}", "detail": " ".join(text.split())[:300]}
    return error_from_problem(problem, status=status, retry_after=retry_after)


__all__ = [
    "PROBLEM_MEDIA_TYPE",
    "PROBLEM_TYPES",
    "TYPE_BASE",
    "ClientTimeout",
    "ConnectionFailed",
    "DefectsOutsideRegion",
    "DegenerateGeometry",
    "EmptyRegion",
    "InternalError",
    "InvalidNormals",
    "InvalidOption",
    "InvalidOutput",
    "InvalidParameter",
    "InvalidRegion",
    "InvalidRequest",
    "MalformedInput",
    "MethodNotAllowed",
    "ModelNotFound",
    "NoSurface",
    "NonFinite",
    "NonOrientable",
    "NormalsRequired",
    "NotFound",
    "NotReady",
    "PayloadTooLarge",
    "QueueFull",
    "RateLimited",
    "RegionError",
    "RegionGrowthExceeded",
    "RegionTooLarge",
    "RequestTimeout",
    "ServerError",
    "ShuttingDown",
    "SpaceMeshError",
    "Timeout",
    "TooExpensive",
    "TooFewPoints",
    "TooManyPoints",
    "TransportError",
    "Unauthorized",
    "Unavailable",
    "Unimplemented",
    "UnsupportedFormat",
    "WholeMeshRegion",
    "error_from_http",
    "error_from_problem",
    "parse_retry_after",
    "slug_of",
]
