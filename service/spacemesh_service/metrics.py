"""Prometheus metrics of one service instance (its own registry, served at ``/metrics``).

``spacemesh_requests_total{protocol,route,status}``
    Requests by route and status (HTTP status code, or gRPC status name).
``spacemesh_request_seconds{protocol,route}``
    End-to-end latency.
``spacemesh_stage_seconds{stage}``
    Per stage: ``decode_input``, ``queue``, ``encoder``, ``sampler``, ``connectivity``,
    ``extraction``, ``encode_output``. The network stages (encoder, sampler,
    connectivity) are observed once per batch; the others once per request.
``spacemesh_queue_depth``, ``spacemesh_inflight_requests``
    Requests waiting for a batch (in both lanes); requests inside the engine (waiting or
    running).
``spacemesh_lane_queue_depth{lane}``, ``spacemesh_lane_running_requests{lane}``,
``spacemesh_lane_requests_total{lane}``
    Per lane (``light``, ``main``): requests waiting, requests in its running batch, and
    requests routed to it by their estimated cost.
``spacemesh_batch_size``, ``spacemesh_batches_total``
    Requests per onnxruntime batch, and batches run.
``spacemesh_cancelled_requests_total``, ``spacemesh_stopped_batches_total``
    Requests given up by their caller (timeout, disconnect) before their result, and
    batches stopped early because all their requests were given up.
``spacemesh_ready``, ``spacemesh_model_info{name,version}``
``spacemesh_repair_stage_seconds{stage}``
    Per stage of a repair: ``decode_input`` (reading the mesh and the region), ``queue``,
    ``cut``, ``patch``, ``encoder``, ``sampler``, ``connectivity``, ``splice``,
    ``encode_output``.
``spacemesh_repairs_total{fallback}``, ``spacemesh_repair_region_faces``
    Repairs done, by fallback (``none``, ``removed-new-vertices``, ``polygon``), and the
    faces each re-generated (the region after growth).
``spacemesh_repair_rejected_total{kind}``
    Repair requests refused for their region (422), by kind (``empty-region``...).
``spacemesh_too_expensive_total{route,option}``
    Requests refused before any work for their estimated cost (422 ``too-expensive``), by
    route (``generate``, ``repair``) and the option named to lower.
"""

from __future__ import annotations

from prometheus_client import CONTENT_TYPE_LATEST as CONTENT_TYPE
from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest

from spacemesh_service.problems import REGION_KINDS

#: Stages of a generate request, in order.
STAGES = ("decode_input", "queue", "encoder", "sampler", "connectivity", "extraction",
          "encode_output")
#: Network stages, timed once per batch.
BATCH_STAGES = ("encoder", "sampler", "connectivity")
#: The lanes (:mod:`spacemesh_service.lanes`).
LANES = ("light", "main")
#: Stages of a repair request, in order.
REPAIR_STAGES = ("decode_input", "queue", "cut", "patch", "encoder", "sampler", "connectivity",
                 "splice", "encode_output")
#: How a repair closed its hole (``RepairStats.fallback``).
REPAIR_FALLBACKS = ("none", "removed-new-vertices", "polygon")

_LATENCY_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.5, 5.0, 10.0,
                    30.0, 60.0)
_BATCH_BUCKETS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 64, 128, 256)
_FACE_BUCKETS = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000)


class Metrics:
    """The instruments, registered in a fresh :class:`CollectorRegistry`."""

    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        r = self.registry
        self.requests = Counter("spacemesh_requests", "Requests by route and status",
                                ["protocol", "route", "status"], registry=r)
        self.request_seconds = Histogram("spacemesh_request_seconds", "End-to-end latency",
                                         ["protocol", "route"], buckets=_LATENCY_BUCKETS,
                                         registry=r)
        self.stage_seconds = Histogram("spacemesh_stage_seconds", "Latency per stage",
                                       ["stage"], buckets=_LATENCY_BUCKETS, registry=r)
        self.queue_depth = Gauge("spacemesh_queue_depth", "Requests waiting for a batch",
                                 registry=r)
        self.lane_queue_depth = Gauge("spacemesh_lane_queue_depth",
                                      "Requests waiting for a batch, per lane", ["lane"],
                                      registry=r)
        self.lane_running = Gauge("spacemesh_lane_running_requests",
                                  "Requests in the running batch, per lane", ["lane"],
                                  registry=r)
        self.lane_requests = Counter("spacemesh_lane_requests",
                                     "Requests routed to each lane by their estimated cost",
                                     ["lane"], registry=r)
        self._depths: dict[str, int] = {}
        self.inflight = Gauge("spacemesh_inflight_requests",
                              "Generate and repair requests inside the engine", registry=r)
        self.batch_size = Histogram("spacemesh_batch_size", "Requests per onnxruntime batch",
                                    buckets=_BATCH_BUCKETS, registry=r)
        self.batches = Counter("spacemesh_batches", "Batches run", registry=r)
        self.cancelled = Counter("spacemesh_cancelled_requests",
                                 "Requests given up before their result", registry=r)
        self.stopped_batches = Counter("spacemesh_stopped_batches",
                                       "Batches stopped because nobody waited", registry=r)
        self.ready = Gauge("spacemesh_ready", "1 once the model is loaded and warm",
                           registry=r)
        self.model_info = Gauge("spacemesh_model_info", "The loaded model",
                                ["name", "version"], registry=r)
        self.repair_stage_seconds = Histogram(
            "spacemesh_repair_stage_seconds", "Latency per stage of a repair", ["stage"],
            buckets=_LATENCY_BUCKETS, registry=r)
        self.repairs = Counter("spacemesh_repairs", "Repairs done, by fallback", ["fallback"],
                               registry=r)
        self.repair_region_faces = Histogram(
            "spacemesh_repair_region_faces", "Faces re-generated per repair",
            buckets=_FACE_BUCKETS, registry=r)
        self.repair_rejected = Counter(
            "spacemesh_repair_rejected", "Repair requests refused for their region (422)",
            ["kind"], registry=r)
        self.too_expensive = Counter(
            "spacemesh_too_expensive", "Requests refused for their estimated cost (422)",
            ["route", "option"], registry=r)
        for lane in LANES:
            self.set_queue_depth(lane, 0)
            self.lane_running.labels(lane).set(0)
            self.lane_requests.labels(lane)
        for stage in STAGES:  # export every stage from the start
            self.stage_seconds.labels(stage)
        for stage in REPAIR_STAGES:
            self.repair_stage_seconds.labels(stage)
        for fallback in REPAIR_FALLBACKS:
            self.repairs.labels(fallback)
        for kind in REGION_KINDS:
            self.repair_rejected.labels(kind.slug)

    def set_queue_depth(self, lane: str, depth: int) -> None:
        """Requests waiting in ``lane``, and in all lanes (``spacemesh_queue_depth``)."""
        self._depths[lane] = depth
        self.lane_queue_depth.labels(lane).set(depth)
        self.queue_depth.set(sum(self._depths.values()))

    def observe_request(self, protocol: str, route: str, status: str, seconds: float) -> None:
        """Count one finished request."""
        self.requests.labels(protocol, route, status).inc()
        self.request_seconds.labels(protocol, route).observe(seconds)

    def observe_stage(self, stage: str, seconds: float) -> None:
        """Record one stage's time."""
        self.stage_seconds.labels(stage).observe(seconds)

    def observe_repair_stage(self, stage: str, seconds: float) -> None:
        """Record one repair stage's time."""
        self.repair_stage_seconds.labels(stage).observe(seconds)

    def render(self) -> bytes:
        """The text exposition format."""
        return generate_latest(self.registry)


__all__ = ["BATCH_STAGES", "CONTENT_TYPE", "LANES", "REPAIR_FALLBACKS", "REPAIR_STAGES", "STAGES",
           "Metrics"]
