"""Every error the service answers, in one place: RFC 9457 problem details.

Each kind has a stable ``type`` URI (``https://spacemesh.dev/problems/<slug>``), a title,
an HTTP status and the gRPC status code the gRPC server ends the call with. Code raises
:class:`Problem`; the REST app renders it as ``application/problem+json`` and the gRPC
server as a status with the type in trailing metadata (``problem-type``, and the
extension members as JSON in ``problem-extensions``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import grpc

#: Base of every problem type URI.
TYPE_BASE = "https://spacemesh.dev/problems/"
#: Media type of problem responses.
PROBLEM_MEDIA_TYPE = "application/problem+json"
#: Longest ``problem-extensions`` trailing metadata value (gRPC limits the metadata).
MAX_GRPC_EXTENSIONS = 4096
#: Path prefix of the KServe v2 routes, whose problems also carry ``error``.
KSERVE_PREFIX = "/v2"


@dataclass(frozen=True)
class ProblemKind:
    """One kind of error.

    Attributes
    ----------
    slug : str
        Last part of the type URI.
    title : str
        Short, human-readable summary (the same for every occurrence).
    status : int
        HTTP status.
    grpc_code : grpc.StatusCode
    """

    slug: str
    title: str
    status: int
    grpc_code: grpc.StatusCode

    @property
    def type(self) -> str:
        """The stable type URI."""
        return TYPE_BASE + self.slug


def _kind(slug: str, title: str, status: int, code: grpc.StatusCode) -> ProblemKind:
    return ProblemKind(slug, title, status, code)


_C = grpc.StatusCode
MALFORMED_INPUT = _kind("malformed-input", "The input could not be read", 400,
                        _C.INVALID_ARGUMENT)
INVALID_PARAMETER = _kind("invalid-parameter", "A request parameter is invalid", 400,
                          _C.INVALID_ARGUMENT)
INVALID_OPTION = _kind("invalid-option", "An option is invalid", 422,
                       _C.INVALID_ARGUMENT)
NOT_FOUND = _kind("not-found", "No such resource", 404, _C.NOT_FOUND)
MODEL_NOT_FOUND = _kind("model-not-found", "No such model or version", 404, _C.NOT_FOUND)
METHOD_NOT_ALLOWED = _kind("method-not-allowed", "Method not allowed", 405, _C.UNIMPLEMENTED)
UNAUTHORIZED = _kind("unauthorized", "A valid API key is required", 401, _C.UNAUTHENTICATED)
REQUEST_TIMEOUT = _kind("request-timeout", "The request body arrived too slowly", 408,
                        _C.DEADLINE_EXCEEDED)
RATE_LIMITED = _kind("rate-limited", "Too many requests", 429, _C.RESOURCE_EXHAUSTED)
PAYLOAD_TOO_LARGE = _kind("payload-too-large", "The request body is too large", 413,
                          _C.RESOURCE_EXHAUSTED)
TOO_MANY_POINTS = _kind("too-many-points", "The point cloud has too many points", 413,
                        _C.RESOURCE_EXHAUSTED)
UNSUPPORTED_FORMAT = _kind("unsupported-format", "Unsupported input format", 415,
                           _C.INVALID_ARGUMENT)
TOO_FEW_POINTS = _kind("too-few-points", "The point cloud has too few points", 422,
                       _C.INVALID_ARGUMENT)
NON_FINITE = _kind("non-finite", "The input has NaN or infinite values", 422,
                   _C.INVALID_ARGUMENT)
DEGENERATE_GEOMETRY = _kind("degenerate-geometry", "The point cloud is degenerate", 422,
                            _C.INVALID_ARGUMENT)
INVALID_NORMALS = _kind("invalid-normals", "The normals do not match the points", 422,
                        _C.INVALID_ARGUMENT)
NORMALS_REQUIRED = _kind("normals-required", "This model needs normals", 422,
                         _C.INVALID_ARGUMENT)
NO_SURFACE = _kind("no-surface", "No surface could be generated from this input", 422,
                   _C.FAILED_PRECONDITION)
# The kind of spacemesh.runtime.budget.CostError (a request over the per-request budget),
# an option error as invalid-option is: the detail names the option to lower.
TOO_EXPENSIVE = _kind("too-expensive", "The request would cost more than this server's "
                      "budget", 422, _C.INVALID_ARGUMENT)
# The repair region kinds: the slugs are spacemesh.repair.region.ERROR_KINDS (a
# RegionError's ``kind``), turned into problems by :func:`region_problem`.
INVALID_REGION = _kind("invalid-region", "The repair region is invalid", 422,
                       _C.INVALID_ARGUMENT)
EMPTY_REGION = _kind("empty-region", "The repair region selects no face", 422,
                     _C.INVALID_ARGUMENT)
WHOLE_MESH_REGION = _kind("whole-mesh-region", "The repair region covers the whole mesh", 422,
                          _C.INVALID_ARGUMENT)
DEFECTS_OUTSIDE_REGION = _kind("defects-outside-region",
                               "The mesh has defects outside the repair region", 422,
                               _C.FAILED_PRECONDITION)
REGION_TOO_LARGE = _kind("region-too-large", "The repair region is too large for the model",
                         422, _C.INVALID_ARGUMENT)
REGION_GROWTH_EXCEEDED = _kind("region-growth-exceeded",
                               "The repair region would grow beyond the allowed share of the "
                               "mesh", 422, _C.INVALID_ARGUMENT)
NON_ORIENTABLE = _kind("non-orientable", "The mesh is not orientable", 422,
                       _C.FAILED_PRECONDITION)
INTERNAL = _kind("internal-error", "Internal server error", 500, _C.INTERNAL)
INVALID_OUTPUT = _kind("invalid-output", "The generated mesh failed validation", 500,
                       _C.INTERNAL)
QUEUE_FULL = _kind("queue-full", "The server is busy", 503, _C.UNAVAILABLE)
NOT_READY = _kind("not-ready", "The model is not ready", 503, _C.UNAVAILABLE)
SHUTTING_DOWN = _kind("shutting-down", "The server is shutting down", 503, _C.UNAVAILABLE)
TIMEOUT = _kind("timeout", "The request took too long", 504, _C.DEADLINE_EXCEEDED)

#: Every kind, by slug (documented in docs/SERVICE.md and the OpenAPI spec).
KINDS: dict[str, ProblemKind] = {
    k.slug: k for k in (
        MALFORMED_INPUT, INVALID_PARAMETER, INVALID_OPTION, NOT_FOUND, MODEL_NOT_FOUND,
        METHOD_NOT_ALLOWED, UNAUTHORIZED, REQUEST_TIMEOUT, RATE_LIMITED,
        PAYLOAD_TOO_LARGE, TOO_MANY_POINTS, UNSUPPORTED_FORMAT, TOO_FEW_POINTS, NON_FINITE,
        DEGENERATE_GEOMETRY, INVALID_NORMALS, NORMALS_REQUIRED, NO_SURFACE, TOO_EXPENSIVE,
        INVALID_REGION,
        EMPTY_REGION, WHOLE_MESH_REGION, DEFECTS_OUTSIDE_REGION, REGION_TOO_LARGE,
        REGION_GROWTH_EXCEEDED, NON_ORIENTABLE, INTERNAL,
        INVALID_OUTPUT, QUEUE_FULL, NOT_READY, SHUTTING_DOWN, TIMEOUT,
    )
}
#: The kinds a repair region can be refused with (422).
REGION_KINDS: tuple[ProblemKind, ...] = (INVALID_REGION, EMPTY_REGION, WHOLE_MESH_REGION,
                                         DEFECTS_OUTSIDE_REGION, REGION_TOO_LARGE,
                                         REGION_GROWTH_EXCEEDED, NON_ORIENTABLE)
#: The kinds a point cloud can be refused with (413, 422): the kinds of
#: :data:`spacemesh.runtime.cloud.ERROR_KINDS`.
CLOUD_KINDS: tuple[ProblemKind, ...] = (DEGENERATE_GEOMETRY, TOO_MANY_POINTS, TOO_FEW_POINTS,
                                        NON_FINITE, INVALID_NORMALS, NORMALS_REQUIRED)


class Problem(Exception):
    """An error answered as problem details.

    Parameters
    ----------
    kind : ProblemKind
    detail : str
        What went wrong with this request, for the person who sent it.
    retry_after : int, optional
        Seconds (sent as ``Retry-After``), for 503s.
    **extra
        Extension members of the problem object (e.g. ``limit``).
    """

    def __init__(self, kind: ProblemKind, detail: str, *, retry_after: int | None = None,
                 **extra: Any) -> None:
        super().__init__(detail)
        self.kind = kind
        self.detail = detail
        self.retry_after = retry_after
        self.extra = extra

    def to_dict(self, instance: str | None = None) -> dict[str, Any]:
        """The problem object (``type``, ``title``, ``status``, ``detail``, ...).

        On the KServe v2 routes (``instance`` under :data:`KSERVE_PREFIX`) it also has
        ``error`` (``"title: detail"``), the member KServe clients such as
        ``tritonclient`` read an error's message from (an RFC 9457 extension member).
        """
        body: dict[str, Any] = {
            "type": self.kind.type, "title": self.kind.title, "status": self.kind.status,
            "detail": self.detail,
        }
        if instance:
            body["instance"] = instance
            if instance == KSERVE_PREFIX or instance.startswith(KSERVE_PREFIX + "/"):
                body["error"] = f"{self.kind.title}: {self.detail}"
        body.update(self.extra)
        return body

    def headers(self) -> dict[str, str]:
        """Response headers (``Retry-After`` when set)."""
        return {"Retry-After": str(self.retry_after)} if self.retry_after is not None else {}

    def grpc_metadata(self) -> tuple[tuple[str, str], ...]:
        """Trailing metadata of the gRPC status: ``problem-type``, ``problem-status``,
        ``retry-after`` (when set) and ``problem-extensions`` (the extension members as
        JSON, when there are any and they fit in :data:`MAX_GRPC_EXTENSIONS` bytes)."""
        items = [("problem-type", self.kind.type), ("problem-status", str(self.kind.status))]
        if self.retry_after is not None:
            items.append(("retry-after", str(self.retry_after)))
        if self.extra:
            try:
                text = json.dumps(_plain(self.extra), separators=(",", ":"), allow_nan=False)
            except (TypeError, ValueError):
                text = ""
            if text and len(text) <= MAX_GRPC_EXTENSIONS:
                items.append(("problem-extensions", text))
        return tuple(items)

    def __repr__(self) -> str:
        return f"Problem({self.kind.slug!r}, {self.detail!r})"


def _plain(value: Any) -> Any:
    """numpy scalars and arrays (and tuples) -> JSON-ready numbers and lists."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, "tolist"):  # numpy array or scalar
        return _plain(value.tolist())
    return value


def typed_problem(error: Any, kinds: tuple[ProblemKind, ...]) -> Problem:
    """The problem of a model-package error that carries a stable ``kind``.

    Its ``kind`` is the problem's slug (one of ``kinds``; the first of them otherwise),
    its message the ``detail`` and its ``details`` the extension members.

    Parameters
    ----------
    error : Exception
        A :class:`spacemesh.repair.RegionError` or a
        :class:`spacemesh.runtime.cloud.CloudError`.
    kinds : tuple of ProblemKind
        The kinds it may map to.

    Returns
    -------
    Problem
    """
    kind = KINDS.get(getattr(error, "kind", ""))
    if kind not in kinds:  # pragma: no cover - the model's errors always have one
        kind = kinds[0]
    problem = Problem(kind, str(error))
    problem.extra.update(_plain(dict(getattr(error, "details", None) or {})))
    return problem


def region_problem(error: Any) -> Problem:
    """The problem (422) of a :class:`spacemesh.repair.RegionError`: its ``kind`` is the
    problem's slug (one of :data:`REGION_KINDS`), its ``details`` (``defects``,
    ``boundary_vertices``...) the extension members."""
    return typed_problem(error, REGION_KINDS)


def too_large_problem(error: Any) -> Problem:
    """The problem (413) of a :class:`spacemesh.io.errors.TooLargeError`: ``too-many-points``
    when a point cloud has more rows than allowed, else ``payload-too-large``; the
    extension members say what was counted (``what``, ``count``, ``limit``)."""
    from spacemesh.io.errors import read_error_kind

    return Problem(KINDS[read_error_kind(error)], str(error), what=error.what,
                   count=error.count, limit=error.limit)


def read_problem(error: Any) -> Problem:
    """The problem of a reader's :class:`spacemesh.io.errors.MeshFormatError`, by its
    kind (:func:`spacemesh.io.errors.read_error_kind`): 413 for a limit
    (:func:`too_large_problem`), 415 for a format no reader takes, 422 for NaN or
    infinity, 400 for a malformed file."""
    from spacemesh.io.errors import TooLargeError, read_error_kind

    if isinstance(error, TooLargeError):
        return too_large_problem(error)
    return Problem(KINDS[read_error_kind(error)], str(error))


def cost_problem(error: Any) -> Problem:
    """The problem (422 ``too-expensive``) of a :class:`spacemesh.runtime.budget.CostError`:
    its ``details`` (``option``, ``estimated_seconds``, ``estimated_mb``, the budget,
    ``savings``, ``suggestion``) are the extension members."""
    return typed_problem(error, (TOO_EXPENSIVE,))


def cloud_problem(error: Any) -> Problem:
    """The problem (413 or 422) of a :class:`spacemesh.runtime.cloud.CloudError`: its
    ``kind`` is the problem's slug (one of :data:`CLOUD_KINDS`), its ``details``
    (``limit``, ``points``, ``singular_values``) the extension members."""
    return typed_problem(error, CLOUD_KINDS)


# ---------------------------------------------------------------------- OpenAPI
def _problem_example(kind: ProblemKind, detail: str, instance: str) -> dict[str, Any]:
    return {"summary": kind.title, "value": {"type": kind.type, "title": kind.title,
                                              "status": kind.status, "detail": detail,
                                              "instance": instance}}


def problem_response(description: str, examples: dict[str, tuple[ProblemKind, str]],
                     retry_after: bool = False, instance: str = "/generate") -> dict[str, Any]:
    """An OpenAPI response of ``application/problem+json`` with named examples (the
    schema is :class:`spacemesh_service.openapi.ProblemModel`)."""
    response: dict[str, Any] = {
        "description": description,
        "content": {PROBLEM_MEDIA_TYPE: {
            "schema": {"$ref": "#/components/schemas/ProblemModel"},
            "examples": {name: _problem_example(k, d, instance)
                         for name, (k, d) in examples.items()},
        }},
    }
    if retry_after:
        response["headers"] = {"Retry-After": {"description": "Seconds to wait.",
                                               "schema": {"type": "integer"}}}
    return response
