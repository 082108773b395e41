"""Every problem kind, raised for real over REST and gRPC, and the two transports agree.

The kinds are read from :data:`spacemesh_service.problems.KINDS`, so a kind added there
without a way to raise it here fails :func:`test_every_kind_has_a_trigger` ("add a
trigger for kind X"). Each trigger makes the server answer the kind on a real server
(the shared one, or one started with the settings or generator the kind needs) and
returns what both transports answered; the checks then hold for every kind:

- REST: the kind's HTTP status, ``application/problem+json``, its ``type``, ``title``
  and ``status`` in the body, a ``detail``;
- gRPC: the kind's status code, ``problem-type`` and ``problem-status`` in the trailing
  metadata, a details string;
- the two agree: the same type, the HTTP status in ``problem-status``, ``Retry-After``
  on both or on neither; and the kind's gRPC code is the one its HTTP status maps to.

A kind only one transport can answer says why in :data:`REST_ONLY`; a kind that needs a
process of its own may name, in :data:`COVERED_ELSEWHERE`, the test that raises it.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import grpc
import httpx
import numpy as np
import pytest
from service_testing import (
    ADMIT_ALL,
    REPAIR_STEPS,
    FailingGenerator,
    GatedGenerator,
    WrappedGenerator,
    faulty_repair,
    mesh_file,
    metric,
    region_pb,
    wait_for,
)

from spacemesh.examples import icosphere
from spacemesh.repair import repair_mesh
from spacemesh_service import problems as P
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

pytestmark = pytest.mark.slow

PROBLEM_MEDIA_TYPE = "application/problem+json"
TESTS = Path(__file__).resolve().parents[1]
C = grpc.StatusCode
#: The gRPC codes an HTTP status may map to (the HTTP to gRPC mapping of the gRPC docs;
#: 422 is a bad argument or a precondition the input fails).
CODES_OF_STATUS: dict[int, set[grpc.StatusCode]] = {
    400: {C.INVALID_ARGUMENT}, 401: {C.UNAUTHENTICATED}, 404: {C.NOT_FOUND},
    405: {C.UNIMPLEMENTED}, 408: {C.DEADLINE_EXCEEDED}, 413: {C.RESOURCE_EXHAUSTED},
    415: {C.INVALID_ARGUMENT}, 422: {C.INVALID_ARGUMENT, C.FAILED_PRECONDITION},
    429: {C.RESOURCE_EXHAUSTED}, 500: {C.INTERNAL}, 503: {C.UNAVAILABLE},
    504: {C.DEADLINE_EXCEEDED},
}


# ---------------------------------------------------------------------- answers
@dataclass(frozen=True)
class RestAnswer:
    status: int
    headers: dict[str, str]
    body: bytes

    @classmethod
    def of(cls, response: httpx.Response) -> RestAnswer:
        return cls(response.status_code, {k.lower(): v for k, v in response.headers.items()},
                   response.content)

    @classmethod
    def parse(cls, raw: bytes) -> RestAnswer:
        """A raw HTTP/1.1 response (read from a socket until the server closed it)."""
        head, _, body = raw.partition(b"\r\n\r\n")
        lines = head.decode("latin-1").split("\r\n")
        headers = dict(line.split(": ", 1) for line in lines[1:] if ": " in line)
        return cls(int(lines[0].split()[1]), {k.lower(): v for k, v in headers.items()}, body)


@dataclass(frozen=True)
class GrpcAnswer:
    code: grpc.StatusCode
    details: str
    metadata: dict[str, str]


def rpc(call: Callable[[], object]) -> GrpcAnswer:
    """Make a call that must fail; what it ended with."""
    with pytest.raises(grpc.RpcError) as info:
        call()
    error = info.value
    return GrpcAnswer(error.code(), error.details() or "", dict(error.trailing_metadata() or ()))


# ---------------------------------------------------------------------- environment
@dataclass
class Env:
    """What the triggers use: the shared server and a way to start others."""

    http: httpx.Client
    stub: pb_grpc.SpaceMeshStub
    case: object
    generator: object
    start_server: Callable
    monkeypatch: pytest.MonkeyPatch
    tmp_path: Path


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield pb_grpc.SpaceMeshStub(channel)


@pytest.fixture
def env(http, stub, case, generator, start_server, monkeypatch, tmp_path) -> Env:
    return Env(http, stub, case, generator, start_server, monkeypatch, tmp_path)


def points_pb(points, normals=None, **fields) -> pb.GenerateRequest:
    normals = [] if normals is None else np.asarray(normals).ravel().tolist()
    return pb.GenerateRequest(points=pb.Points(xyz=np.asarray(points).ravel().tolist(),
                                               normals=normals), **fields)


def file_pb(data: bytes, filename: str, **fields) -> pb.GenerateRequest:
    return pb.GenerateRequest(file=pb.PointCloudFile(data=data, filename=filename), **fields)


def post_points(http: httpx.Client, points, **body) -> RestAnswer:
    return RestAnswer.of(http.post("/generate", json={"points": np.asarray(points).tolist(),
                                                      **body}))


def post_repair(http: httpx.Client, mesh, region: dict, **params) -> RestAnswer:
    return RestAnswer.of(http.post(
        "/repair", params={"format": "obj", "steps": REPAIR_STEPS, **params},
        files={"file": ("mesh.obj", mesh_file(mesh))}, data={"region": json.dumps(region)}))


def repair_rpc(stub, mesh, region: dict, **fields) -> GrpcAnswer:
    request = pb.RepairRequest(mesh=mesh_file(mesh), filename="mesh.obj",
                               region=region_pb(region), steps=REPAIR_STEPS, **fields)
    return rpc(lambda: stub.Repair(request))


def both_repair(env: Env, mesh, region: dict, **params) -> tuple[RestAnswer, GrpcAnswer]:
    return (post_repair(env.http, mesh, region, **params),
            repair_rpc(env.stub, mesh, region, **params))


def both_points(env: Env, points, normals=None, **options) -> tuple[RestAnswer, GrpcAnswer]:
    body = dict(options) if normals is None else {**options, "normals": np.asarray(
        normals).tolist()}
    return (post_points(env.http, points, **body),
            rpc(lambda: env.stub.Generate(points_pb(points, normals, **options))))


def on_server(server) -> tuple[httpx.Client, pb_grpc.SpaceMeshStub, grpc.Channel]:
    channel = grpc.insecure_channel(server.grpc_target)
    return (httpx.Client(base_url=server.url, timeout=60), pb_grpc.SpaceMeshStub(channel),
            channel)


# ---------------------------------------------------------------------- triggers
Answers = tuple[RestAnswer | None, GrpcAnswer | None]


def malformed_input(env: Env) -> Answers:
    rest = env.http.post("/generate", content=b"{not json",
                         headers={"content-type": "application/json"})
    return RestAnswer.of(rest), rpc(lambda: env.stub.Generate(pb.GenerateRequest()))


def invalid_parameter(env: Env) -> Answers:
    rest = env.http.post("/ui/preview", files={"file": ("c.xyz", b"0 0 0\n1 0 0\n0 1 0\n")},
                         data={"kind": "x"})
    return RestAnswer.of(rest), None


def invalid_option(env: Env) -> Answers:
    return both_points(env, env.case.points, steps=10_000)


def not_found(env: Env) -> Answers:
    return RestAnswer.of(env.http.get("/nowhere")), None


def model_not_found(env: Env) -> Answers:
    return RestAnswer.of(env.http.get("/v2/models/no-such-model")), None


def method_not_allowed(env: Env) -> Answers:
    return RestAnswer.of(env.http.get("/generate")), None


def unauthorized(env: Env) -> Answers:
    keys = env.tmp_path / "keys.txt"
    keys.write_text("# the only key\nkind-table-key\n")
    server = env.start_server(env.generator, warmup=False, api_keys=keys)
    http, stub, channel = on_server(server)
    with http, channel:
        rest = post_points(http, env.case.points[:5])  # no key: refused before the body
        return rest, rpc(lambda: stub.Generate(points_pb(env.case.points[:5]),
                                               metadata=(("authorization", "Bearer wrong"),)))


def request_timeout(env: Env) -> Answers:
    server = env.start_server(env.generator, warmup=False, body_timeout_s=0.5)
    with socket.create_connection(("127.0.0.1", server.server.http_port), timeout=10) as sock:
        sock.sendall(b"POST /generate HTTP/1.1\r\nHost: x\r\nContent-Type: application/json"
                     b"\r\nContent-Length: 100000\r\n\r\n{\"points\": [")  # and no more
        raw = b""
        while chunk := sock.recv(65536):
            raw += chunk
    return RestAnswer.parse(raw), None


def rate_limited(env: Env) -> Answers:
    server = env.start_server(env.generator, warmup=False, rate_limit=0.001, rate_burst=1)
    http, stub, channel = on_server(server)
    with http, channel:
        assert post_points(http, env.case.points[:5]).status == 422  # the burst: one
        rest = post_points(http, env.case.points[:5])
        # one bucket per client address for both ports: gRPC is limited as well
        return rest, rpc(lambda: stub.Generate(points_pb(env.case.points[:5])))


def payload_too_large(env: Env) -> Answers:
    big = b"0 0 0\n" * 400_000  # 2.4 MB > the 2 MB limit
    rest = env.http.post("/generate", files={"file": ("c.xyz", big)})
    return RestAnswer.of(rest), rpc(lambda: env.stub.Generate(file_pb(big, "c.xyz")))


def too_many_points(env: Env) -> Answers:
    return both_points(env, np.random.default_rng(0).standard_normal((5001, 3)))


def unsupported_format(env: Env) -> Answers:
    junk = bytes(range(256)) * 4
    rest = env.http.post("/generate", files={"file": ("c.docx", junk)})
    return RestAnswer.of(rest), rpc(lambda: env.stub.Generate(file_pb(junk, "c.docx")))


def too_few_points(env: Env) -> Answers:
    return both_points(env, env.case.points[:5])


def non_finite(env: Env) -> Answers:
    points = env.case.points.copy()
    points[7] = np.nan
    text = "".join(f"{x} {y} {z}\n" for x, y, z in points.tolist()).encode()
    rest = env.http.post("/generate", files={"file": ("c.xyz", text)})
    return RestAnswer.of(rest), rpc(lambda: env.stub.Generate(points_pb(points)))


def degenerate_geometry(env: Env) -> Answers:
    return both_points(env, np.ones((40, 3)))


def invalid_normals(env: Env) -> Answers:
    return both_points(env, env.case.points, normals=env.case.points[:5])


class NormalsGenerator(WrappedGenerator):
    """The real generator presented as a model that reads normals."""

    def __init__(self, inner) -> None:
        super().__init__(inner)
        self.spec = replace(inner.spec, normals=True)


def normals_required(env: Env) -> Answers:
    server = env.start_server(NormalsGenerator(env.generator), warmup=False)
    http, stub, channel = on_server(server)
    with http, channel:
        return post_points(http, env.case.points), rpc(
            lambda: stub.Generate(points_pb(env.case.points)))


def too_expensive(env: Env) -> Answers:
    server = env.start_server(env.generator, warmup=False, request_budget_s=5)
    http, stub, channel = on_server(server)
    with http, channel:
        options = {"start": "points", "target_vertices": 10_000}  # estimated far over 5 s
        return post_points(http, env.case.points, **options), rpc(
            lambda: stub.Generate(points_pb(env.case.points, **options)))


def no_surface(env: Env) -> Answers:
    return both_points(env, env.case.points, **env.case.no_surface)  # checked by `case`


SPHERE = icosphere(1)


def invalid_region(env: Env) -> Answers:
    return both_repair(env, SPHERE, {"sphere": {"center": [0, 0, 0], "radius": -1}})


def empty_region(env: Env) -> Answers:
    return both_repair(env, SPHERE, {"sphere": {"center": [9, 9, 9], "radius": 0.1}})


def whole_mesh_region(env: Env) -> Answers:
    return both_repair(env, SPHERE, {"faces": list(range(SPHERE.n_faces))})


def defects_outside_region(env: Env) -> Answers:
    from tests.repair.test_repair_cut import open_icosphere

    mesh = open_icosphere()[0]
    return both_repair(env, mesh, {"sphere": {"center": (-mesh.vertices[0]).tolist(),
                                              "radius": 0.3}})


def region_too_large(env: Env) -> Answers:
    band = {"box": {"min": [-1, -1, -0.1], "max": [1, 1, 0.1]}}  # more than 64 tokens
    return both_repair(env, icosphere(3), band)


def region_growth_exceeded(env: Env) -> Answers:
    # two faces meeting only at vertex 0 grow to its 5 faces: 6 % of 80, over 5 %
    around = np.unique(SPHERE.face_of_corner[SPHERE.face_indices == 0])
    faces = {int(f): set(SPHERE.faces[f].tolist()) for f in around}
    pair = next([a, b] for a in faces for b in faces if a < b and faces[a] & faces[b] == {0})
    return both_repair(env, SPHERE, {"faces": pair}, max_growth=0.05)


def non_orientable(env: Env) -> Answers:
    from tests.repair.auto_meshes import moebius

    return both_repair(env, moebius(), {"auto": "holes"})


def internal_error(env: Env) -> Answers:
    server = env.start_server(FailingGenerator(env.generator), warmup=False)
    http, stub, channel = on_server(server)
    with http, channel:
        return post_points(http, env.case.points, seed=env.case.good_seed), rpc(
            lambda: stub.Generate(points_pb(env.case.points, seed=env.case.good_seed)))


def invalid_output(env: Env) -> Answers:
    import spacemesh_service.engine as engine_module

    # a repair that moves a face outside its region: refused by the server's check
    env.monkeypatch.setattr(engine_module, "repair_mesh", faulty_repair(repair_mesh))
    server = env.start_server(env.generator, warmup=False)
    http, stub, channel = on_server(server)
    with http, channel:
        region = {"faces": [0, 1]}
        return post_repair(http, SPHERE, region), repair_rpc(stub, SPHERE, region)


def queue_full(env: Env) -> Answers:
    gated = GatedGenerator(env.generator)
    server = env.start_server(gated, warmup=False, max_batch_size=1, queue_size=1,
                              max_batch_delay_ms=0, drain_timeout_s=1)
    http, stub, channel = on_server(server)
    try:
        with http, channel, ThreadPoolExecutor(2) as pool:
            running = pool.submit(post_points, http, env.case.points, seed=env.case.good_seed)
            assert gated.entered.wait(30)
            queued = pool.submit(post_points, http, env.case.points, seed=env.case.good_seed)
            wait_for(lambda: metric(server.url, "spacemesh_queue_depth") == 1,
                     "one queued request")
            answers = (post_points(http, env.case.points),
                       rpc(lambda: stub.Generate(points_pb(env.case.points))))
            gated.gate.set()
            assert running.result().status == queued.result().status == 200
            return answers
    finally:
        gated.gate.set()


def not_ready(env: Env) -> Answers:
    gated = GatedGenerator(env.generator)  # the warm-up waits at the gate
    server = env.start_server(gated, wait_ready=False, warmup=True, drain_timeout_s=1)
    http, stub, channel = on_server(server)
    try:
        with http, channel:
            return post_points(http, env.case.points), rpc(
                lambda: stub.Generate(points_pb(env.case.points)))
    finally:
        gated.gate.set()


def shutting_down(env: Env) -> Answers:
    server = env.start_server(env.generator, warmup=False, drain_timeout_s=1)
    http, stub, channel = on_server(server)
    with http, channel:
        assert http.get("/v2/health/live").status_code == 200  # both connections open
        stub_ready = rpc(lambda: stub.Generate(pb.GenerateRequest()))
        assert stub_ready.code == C.INVALID_ARGUMENT
        # the drain's first step (SIGTERM): refuse new work while the ports still answer
        server.server.engine.begin_drain()
        return post_points(http, env.case.points), rpc(
            lambda: stub.Generate(points_pb(env.case.points)))


def timeout(env: Env) -> Answers:
    gated = GatedGenerator(env.generator)
    server = env.start_server(gated, warmup=False, max_batch_size=1, queue_size=4,
                              max_batch_delay_ms=0, request_timeout_s=0.5, drain_timeout_s=1,
                              **ADMIT_ALL)
    http, stub, channel = on_server(server)
    try:
        with http, channel:
            rest = post_points(http, env.case.points, start="noise")  # held at the gate
            return rest, rpc(lambda: stub.Generate(points_pb(env.case.points)))  # queued
    finally:
        gated.gate.set()


#: How to raise each kind (slug -> trigger).
TRIGGERS: dict[str, Callable[[Env], Answers]] = {
    "malformed-input": malformed_input,
    "invalid-parameter": invalid_parameter,
    "invalid-option": invalid_option,
    "not-found": not_found,
    "model-not-found": model_not_found,
    "method-not-allowed": method_not_allowed,
    "unauthorized": unauthorized,
    "request-timeout": request_timeout,
    "rate-limited": rate_limited,
    "payload-too-large": payload_too_large,
    "too-many-points": too_many_points,
    "unsupported-format": unsupported_format,
    "too-few-points": too_few_points,
    "non-finite": non_finite,
    "degenerate-geometry": degenerate_geometry,
    "invalid-normals": invalid_normals,
    "normals-required": normals_required,
    "no-surface": no_surface,
    "too-expensive": too_expensive,
    "invalid-region": invalid_region,
    "empty-region": empty_region,
    "whole-mesh-region": whole_mesh_region,
    "defects-outside-region": defects_outside_region,
    "region-too-large": region_too_large,
    "region-growth-exceeded": region_growth_exceeded,
    "non-orientable": non_orientable,
    "internal-error": internal_error,
    "invalid-output": invalid_output,
    "queue-full": queue_full,
    "not-ready": not_ready,
    "shutting-down": shutting_down,
    "timeout": timeout,
}
#: Kinds only REST can answer, and why gRPC cannot.
REST_ONLY: dict[str, str] = {
    "invalid-parameter": "every parameter of a gRPC request is an option (invalid-option) or "
                         "a typed field; the parameters that are not options (the page's "
                         "/ui/preview kind) are REST's",
    "not-found": "a URL path; grpc itself answers an unknown method UNIMPLEMENTED",
    "model-not-found": "the KServe model metadata routes are REST only",
    "method-not-allowed": "an HTTP method; a gRPC method has none",
    "request-timeout": "a REST body read; gRPC receives a message whole before a handler "
                       "runs, and its connection limits end the connection",
}
#: Kinds raised by another test (one that needs its own process, say): slug -> "file::test".
COVERED_ELSEWHERE: dict[str, str] = {}


def test_every_kind_has_a_trigger():
    missing = [slug for slug in P.KINDS if slug not in TRIGGERS and slug not in
               COVERED_ELSEWHERE]
    assert not missing, "; ".join(
        f"add a trigger for kind {slug} to TRIGGERS in {Path(__file__).name} (or name the "
        "test that raises it in COVERED_ELSEWHERE)" for slug in missing)
    stale = (set(TRIGGERS) | set(COVERED_ELSEWHERE) | set(REST_ONLY)) - set(P.KINDS)
    assert not stale, f"triggers of kinds that no longer exist: {sorted(stale)}"
    for slug, where in COVERED_ELSEWHERE.items():
        path, _, name = where.partition("::")
        text = (TESTS.parent / path).read_text()
        assert f"def {name}(" in text and slug in text, (slug, where)


def test_every_status_maps_to_its_grpc_code():
    for kind in P.KINDS.values():
        assert kind.grpc_code in CODES_OF_STATUS[kind.status], kind


@pytest.mark.parametrize("slug", sorted(P.KINDS))
def test_each_kind_over_rest_and_grpc(env, slug):
    if slug not in TRIGGERS:
        if slug in COVERED_ELSEWHERE:
            return  # checked by test_every_kind_has_a_trigger
        pytest.fail(f"add a trigger for kind {slug}")
    kind = P.KINDS[slug]
    rest, call = TRIGGERS[slug](env)
    assert rest is not None, f"{slug}: every kind is answered over REST"
    assert rest.status == kind.status, (slug, rest.status, rest.body[:300])
    assert rest.headers["content-type"].startswith(PROBLEM_MEDIA_TYPE), slug
    body = json.loads(rest.body)
    assert (body["type"], body["title"], body["status"]) == (kind.type, kind.title,
                                                             kind.status), body
    assert body["detail"], body
    if call is None:
        assert slug in REST_ONLY, f"{slug}: no gRPC answer, and REST_ONLY does not say why"
        return
    assert slug not in REST_ONLY, f"{slug} is answered over gRPC: drop it from REST_ONLY"
    assert call.code == kind.grpc_code, (slug, call.code, call.details)
    assert call.metadata.get("problem-type") == body["type"], (slug, call.metadata)
    assert call.metadata.get("problem-status") == str(rest.status), (slug, call.metadata)
    assert call.details, slug
    assert ("retry-after" in rest.headers) == ("retry-after" in call.metadata), slug
