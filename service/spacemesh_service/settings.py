"""Service configuration: one field per ``spacemesh serve`` flag, each with an environment
variable of the same name (``--max-batch-size`` is ``SPACEMESH_MAX_BATCH_SIZE``).

Precedence: an explicit value (a command-line flag, or a keyword of
:meth:`Settings.from_env`) over the environment over the default below. The command line
is built from these fields (:mod:`spacemesh.cli.serve`), so a new field is a new flag.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator

from spacemesh.io.reduce import DEFAULT_MAX_BINARY_POINTS, DEFAULT_WORKING_POINTS
from spacemesh.runtime.budget import Budget
from spacemesh.runtime.cloud import DEFAULT_MAX_POINTS, DEFAULT_MIN_POINTS
from spacemesh_service.networks import parse_networks

#: Prefix of every environment variable.
ENV_PREFIX = "SPACEMESH_"
#: The default time budget of a request, in request deadlines (``request_timeout_s``).
BUDGET_DEADLINES = 2.0
#: The default memory budget of a request (MB).
DEFAULT_BUDGET_MB = 2048.0
#: The default light lane: requests estimated within this share of the request deadline.
LIGHT_LANE_DEADLINES = 0.25
#: The default light lane's memory: requests estimated at most this many MB.
DEFAULT_LIGHT_LANE_MB = 512.0


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


class Settings(BaseModel):
    """Everything the service can be told. See the module docstring for the env vars."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    model: Path | None = Field(
        None, description="Model repository (version folder, model folder or root); "
        "default: the shipped models/spacemesh-small.")
    host: str = Field("127.0.0.1", description="Interface to listen on (0.0.0.0 for all).")
    port: int = Field(8000, ge=0, le=65535, description="REST port (0: any free port).")
    grpc_port: int = Field(8001, ge=0, le=65535, description="gRPC port (0: any free port).")
    grpc: bool = Field(True, description="Serve gRPC besides REST.")
    max_batch_size: int = Field(4, ge=1, le=256,
                                description="Most requests in one onnxruntime batch.")
    max_batch_delay_ms: float = Field(
        5.0, ge=0, le=10_000,
        description="How long the first request of a batch waits for others (ms).")
    queue_size: int = Field(32, ge=1, description="Requests that may wait; beyond: 503.")
    request_timeout_s: float = Field(
        30.0, gt=0, description="Per-request limit (queue + inference) before a 504.")
    request_budget_s: float | None = Field(
        None, gt=0, description="Most seconds a generate or repair request is estimated "
        "to take (spacemesh.runtime.cost, on the 2-core reference machine) before any work "
        "starts; over it: 422 too-expensive naming the option to lower. Default: twice "
        "request_timeout_s.")
    request_budget_mb: float = Field(
        DEFAULT_BUDGET_MB, gt=0, description="Most peak memory (MB) a generate or repair "
        "request is estimated to take; over it: 422 too-expensive.")
    light_lane_s: float | None = Field(
        None, ge=0, description="Requests estimated at most this many seconds (and "
        "light_lane_mb) wait and run in the light lane, a queue and inference thread of "
        "their own, so that a heavy request never holds them up; the others go to the "
        "main lane (0: one lane for everything). Default: a quarter of request_timeout_s.")
    light_lane_mb: float = Field(
        DEFAULT_LIGHT_LANE_MB, gt=0, description="Most peak memory (MB) a request of the "
        "light lane is estimated to take.")
    max_points: int = Field(
        DEFAULT_MAX_BINARY_POINTS, ge=1, description="Most points of a request (413 above): "
        "binary PLY, NPY, NPZ, LAS and LAZ clouds, read as views over their bytes or a "
        "block at a time.")
    max_text_points: int = Field(
        DEFAULT_MAX_POINTS, ge=1, description="Most points of a cloud parsed from text "
        "(XYZ/PTS/TXT/CSV, ASCII PLY, OBJ, a JSON body, gRPC numbers) or read from a mesh "
        "format's vertices (413 above; max_points applies too).")
    working_points: int = Field(
        DEFAULT_WORKING_POINTS, ge=16, description="A cloud of more points is reduced to "
        "this many (a seeded uniform random subset) before generation.")
    min_points: int = Field(DEFAULT_MIN_POINTS, ge=1,
                            description="Fewest points per request (422 below).")
    max_upload_bytes: int = Field(
        512 * 1024 * 1024, ge=1, description="Largest request body and gRPC message (413 "
        "above): room for 10 million points with normals in float64.")
    max_text_bytes: int = Field(
        32 * 1024 * 1024, ge=1, description="Largest upload other than a binary PLY, NPY, "
        "NPZ, LAS or LAZ point cloud: text clouds, JSON bodies and mesh files (413 above).")
    max_mesh_vertices: int = Field(
        1_000_000, ge=1, description="Most vertices of an uploaded mesh (repair), checked "
        "while it is read (413 above).")
    max_mesh_faces: int = Field(
        2_000_000, ge=1, description="Most faces of an uploaded mesh (repair; triangles of "
        "STL and glTF), checked while it is read (413 above).")
    max_parallel_parses: int = Field(
        2, ge=1, description="Uploads parsed at once (the others wait): bounds the memory "
        "that parsing takes (docs/SERVICE.md, Memory bound).")
    default_steps: int | None = Field(
        None, ge=1, description="Sampler steps when a request gives none (default: the "
        "model's).")
    max_steps: int = Field(
        1024, ge=1, description="Most sampler steps a request may ask for (also capped by "
        "the model's timesteps).")
    max_repair_growth: float = Field(
        1.0, ge=0, le=1, description="Largest max_growth a repair request may ask for (the "
        "share of the mesh's faces a region may grow to; the default is 0.25).")
    ort_threads: int = Field(
        0, ge=0, description="Threads that run the networks' batch items at once (0: one per "
        "available core); each graph call runs one item on one onnxruntime thread, so the "
        "meshes are the same whatever this count.")
    warmup: bool = Field(True, description="Run a warm-up inference before reporting ready.")
    drain_timeout_s: float = Field(
        30.0, ge=0, description="On SIGTERM, how long in-flight requests may still run.")
    drain_notice_s: float = Field(
        2.0, ge=0, description="On SIGTERM, how long at least both servers keep answering "
        "new requests with 503 shutting-down (gRPC UNAVAILABLE) before they close, so that "
        "a load balancer that has not yet seen readiness turn false gets an answer to retry "
        "elsewhere rather than a refused connection (at most drain_timeout_s).")
    log_level: str = Field("info", description="Log level (debug, info, warning, error).")
    # connections (spacemesh_service.connections)
    header_timeout_s: float = Field(
        10.0, gt=0, description="REST: a connection that has not sent a request's headers "
        "within this many seconds of connecting (or of starting them) is closed; gRPC: the "
        "connection handshake limit.")
    body_timeout_s: float = Field(
        60.0, gt=0, description="REST: the whole body must arrive within this many seconds "
        "of the headers (408 request-timeout otherwise).")
    idle_timeout_s: float = Field(
        5.0, gt=0, description="REST: an idle keep-alive connection is closed after this "
        "many seconds.")
    grpc_idle_timeout_s: float = Field(
        300.0, gt=0, description="gRPC: a connection without calls for this many seconds "
        "is closed (GOAWAY).")
    grpc_max_connection_age_s: float = Field(
        300.0, ge=0, description="gRPC: connections are closed (GOAWAY) at this age in "
        "seconds, running calls get drain_timeout_s more; clients reconnect on their own. "
        "It bounds how long a trickled message can hold a connection (0: no limit).")
    grpc_keepalive_s: float = Field(
        60.0, gt=0, description="gRPC: ping a connection without traffic this often (s).")
    grpc_keepalive_timeout_s: float = Field(
        20.0, gt=0, description="gRPC: close a connection whose ping is not answered "
        "within this many seconds.")
    access_log: bool = Field(
        True, description="One JSON line per request on the spacemesh.access logger (INFO).")
    # protection (spacemesh_service.security; all off by default)
    api_keys: Path | None = Field(
        None, description="File of API keys, one a line (blank and # lines ignored): every "
        "route but health and the web page then needs 'Authorization: Bearer KEY'.")
    public_metrics: bool = Field(
        False, description="With --api-keys: leave /metrics open (for a scraper inside "
        "the cluster).")
    rate_limit: float = Field(
        0.0, ge=0, description="Requests a second per API key (per client address without "
        "keys); 429 beyond (0: no limit).")
    rate_burst: int = Field(10, ge=1, description="Requests a client may make at once "
                            "before --rate-limit applies.")
    trusted_proxies: str = Field(
        "", description="Comma-separated CIDRs of proxies whose X-Forwarded-For gives the "
        "client address (for rate limits and access logs).")
    tls_cert: Path | None = Field(
        None, description="TLS certificate chain (PEM) for both REST and gRPC; needs "
        "--tls-key.")
    tls_key: Path | None = Field(
        None, validate_default=True, description="TLS private key (PEM); needs --tls-cert.")
    ui: bool = Field(True, description="Serve the web page at / (and its assets under "
                     "/static); --no-ui turns it off.")

    @field_validator("trusted_proxies")
    @classmethod
    def _networks(cls, value: str) -> str:
        parse_networks(value)
        return value

    @field_validator("tls_key")
    @classmethod
    def _tls_pair(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        if (value is None) != (info.data.get("tls_cert") is None):
            raise ValueError("--tls-cert and --tls-key go together: give both or neither")
        return value

    @classmethod
    def env_name(cls, field: str) -> str:
        """The environment variable of a field (``port`` -> ``SPACEMESH_PORT``)."""
        return ENV_PREFIX + field.upper()

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None, **overrides: Any) -> Settings:
        """Settings from explicit values, then ``SPACEMESH_*`` variables, then defaults.

        Parameters
        ----------
        environ : dict, optional
            The environment (default ``os.environ``).
        **overrides
            Explicit values; None means "not given".

        Returns
        -------
        Settings

        Raises
        ------
        ValueError
            A value does not parse or is out of range (the message names the variable).
        """
        env: Mapping[str, str] = os.environ if environ is None else environ
        values: dict[str, Any] = {}
        for name in cls.model_fields:
            raw = env.get(cls.env_name(name))
            if raw is not None and raw != "":
                values[name] = raw
        values.update({k: v for k, v in overrides.items() if v is not None})
        try:
            return cls.model_validate(values, strict=False)
        except ValidationError as error:
            first = error.errors()[0]
            field = str(first["loc"][0]) if first["loc"] else "?"
            raise ValueError(
                f"invalid setting {field} (--{field.replace('_', '-')} / "
                f"{cls.env_name(field)}): {first['msg']}"
            ) from None

    @property
    def budget(self) -> Budget:
        """What one generate or repair request may cost (its estimate, before any work):
        ``request_budget_s`` (default: :data:`BUDGET_DEADLINES` request deadlines) and
        ``request_budget_mb``."""
        seconds = self.request_budget_s or BUDGET_DEADLINES * self.request_timeout_s
        return Budget(seconds, self.request_budget_mb)

    @property
    def light_lane(self) -> Budget | None:
        """What a request of the light lane may cost (its estimate): ``light_lane_s``
        (default: :data:`LIGHT_LANE_DEADLINES` of the request deadline) and
        ``light_lane_mb``; None when ``light_lane_s`` is 0 (one lane)."""
        seconds = (LIGHT_LANE_DEADLINES * self.request_timeout_s
                   if self.light_lane_s is None else self.light_lane_s)
        return Budget(seconds, self.light_lane_mb) if seconds > 0 else None

    @property
    def network_threads(self) -> int:
        """The threads that run the networks' batch items, always explicit (never 0)."""
        return self.ort_threads or _cpu_count()

    def limits(self) -> dict[str, Any]:
        """The request limits, as reported by the model metadata."""
        return {
            "min_points": self.min_points,
            "max_points": self.max_points,
            "max_text_points": self.max_text_points,
            "working_points": self.working_points,
            "max_upload_bytes": self.max_upload_bytes,
            "max_text_bytes": self.max_text_bytes,
            "max_mesh_vertices": self.max_mesh_vertices,
            "max_mesh_faces": self.max_mesh_faces,
            "max_steps": self.max_steps,
            "request_timeout_s": self.request_timeout_s,
            "request_budget_s": self.budget.seconds,
            "request_budget_mb": self.request_budget_mb,
            "light_lane_s": 0.0 if self.light_lane is None else self.light_lane.seconds,
            "light_lane_mb": self.light_lane_mb,
            "max_batch_size": self.max_batch_size,
            "max_batch_delay_ms": self.max_batch_delay_ms,
            "queue_size": self.queue_size,
        }
