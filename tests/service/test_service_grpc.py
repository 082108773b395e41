"""The gRPC API on a real server: Generate, GenerateStream, Repair, health, parity with REST."""

from __future__ import annotations

import grpc
import numpy as np
import pytest
from grpc_health.v1 import health_pb2, health_pb2_grpc
from service_testing import UPLOADS

from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def channel(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield channel


@pytest.fixture(scope="module")
def stub(channel):
    return pb_grpc.SpaceMeshStub(channel)


def points_request(points, **options) -> pb.GenerateRequest:
    return pb.GenerateRequest(points=pb.Points(xyz=np.asarray(points).ravel().tolist()),
                              **options)


def file_request(name: str, points, **options) -> pb.GenerateRequest:
    filename, encode = UPLOADS[name]
    return pb.GenerateRequest(file=pb.PointCloudFile(data=encode(points), filename=filename),
                              **options)


def problem_of(error: grpc.RpcError) -> dict[str, str]:
    return dict(error.trailing_metadata() or ())


def assert_rpc_problem(call, code: grpc.StatusCode, slug: str) -> dict[str, str]:
    with pytest.raises(grpc.RpcError) as info:
        call()
    assert info.value.code() == code, info.value.details()
    metadata = problem_of(info.value)
    assert metadata["problem-type"] == f"https://spacemesh.dev/problems/{slug}"
    return metadata


@pytest.mark.parametrize("fmt", ["glb", "obj", "json"])
def test_rest_and_grpc_give_byte_identical_meshes(stub, http, case, fmt):
    seed = case.good_seed
    rest_json = http.post("/generate", json={"points": case.points.tolist(), "seed": seed,
                                             "format": fmt})
    rest_file = http.post("/generate", params={"seed": seed, "format": fmt},
                          files={"file": ("cloud.ply", UPLOADS["ply"][1](case.points))})
    assert rest_json.status_code == rest_file.status_code == 200
    by_points = stub.Generate(points_request(case.points, seed=seed, format=fmt))
    by_file = stub.Generate(file_request("ply", case.points, seed=seed, format=fmt))
    assert by_points.mesh == rest_json.content
    assert by_file.mesh == rest_file.content
    assert by_points.media_type == rest_json.headers["content-type"]
    stats = by_points.stats
    assert stats.vertices == int(rest_json.headers["x-spacemesh-vertices"])
    assert stats.faces == int(rest_json.headers["x-spacemesh-faces"])
    assert stats.manifold and stats.closed and stats.oriented
    assert by_points.seed == seed and by_points.batch_size >= 1
    assert set(by_points.timings) >= {"decode_input", "encoder", "sampler", "connectivity",
                                      "extraction", "encode_output", "total"}


def test_generate_stream_reports_every_step_then_the_mesh(stub, case, generator):
    steps = 5
    events = list(stub.GenerateStream(points_request(case.points, seed=case.good_seed,
                                                     steps=steps, format="obj",
                                                     start="noise")))
    progress = [e.progress for e in events[:-1]]
    assert all(e.WhichOneof("event") == "progress" for e in events[:-1])
    # without GenerateRequest.stages: the diffusion steps only, as older clients expect
    assert [(p.step, p.total) for p in progress] == [(i, steps) for i in range(1, steps + 1)]
    assert {p.stage for p in progress} == {"sampler"}
    last = events[-1]
    assert last.WhichOneof("event") == "mesh" and last.mesh.steps == steps
    unary = stub.Generate(points_request(case.points, seed=case.good_seed, steps=steps,
                                         format="obj", start="noise"))
    assert last.mesh.mesh == unary.mesh


def test_grpc_errors_carry_the_problem_type(stub, case):
    assert_rpc_problem(lambda: stub.Generate(points_request(case.points[:5])),
                       grpc.StatusCode.INVALID_ARGUMENT, "too-few-points")
    assert_rpc_problem(lambda: stub.Generate(pb.GenerateRequest()),
                       grpc.StatusCode.INVALID_ARGUMENT, "malformed-input")
    junk = pb.GenerateRequest(file=pb.PointCloudFile(data=bytes(range(256)), filename="a.doc"))
    assert_rpc_problem(lambda: stub.Generate(junk), grpc.StatusCode.INVALID_ARGUMENT,
                       "unsupported-format")
    many = np.random.default_rng(0).standard_normal((5001, 3))
    metadata = assert_rpc_problem(lambda: stub.Generate(points_request(many)),
                                  grpc.StatusCode.RESOURCE_EXHAUSTED, "too-many-points")
    assert metadata["problem-status"] == "413"
    big = pb.GenerateRequest(file=pb.PointCloudFile(data=b"0 0 0\n" * 400_000,
                                                    filename="c.xyz"))  # 2.4 MB > 2 MB
    assert_rpc_problem(lambda: stub.Generate(big), grpc.StatusCode.RESOURCE_EXHAUSTED,
                       "payload-too-large")
    assert_rpc_problem(lambda: stub.Generate(points_request(case.points, steps=10_000)),
                       grpc.StatusCode.INVALID_ARGUMENT, "invalid-option")
    assert_rpc_problem(lambda: stub.Generate(points_request(np.ones((40, 3)))),
                       grpc.StatusCode.INVALID_ARGUMENT, "degenerate-geometry")
    assert_rpc_problem(lambda: list(stub.GenerateStream(points_request(case.points[:5]))),
                       grpc.StatusCode.INVALID_ARGUMENT, "too-few-points")
    assert_rpc_problem(lambda: stub.Generate(points_request(case.points, **case.no_surface)),
                       grpc.StatusCode.FAILED_PRECONDITION, "no-surface")


def test_repair_without_a_region_is_malformed(stub):
    # Repair itself: tests/service/test_service_repair.py
    assert_rpc_problem(lambda: stub.Repair(pb.RepairRequest(mesh=b"OFF\n0 0 0\n")),
                       grpc.StatusCode.INVALID_ARGUMENT, "malformed-input")


def test_health_v1(channel):
    health = health_pb2_grpc.HealthStub(channel)
    serving = health_pb2.HealthCheckResponse.SERVING
    assert health.Check(health_pb2.HealthCheckRequest(service="")).status == serving
    named = health_pb2.HealthCheckRequest(service="spacemesh.v1.SpaceMesh")
    assert health.Check(named).status == serving


def test_grpc_requests_are_counted(stub, http, case):
    stub.Generate(points_request(case.points, seed=case.good_seed))
    text = http.get("/metrics").text
    assert ('spacemesh_requests_total{protocol="grpc",route="/spacemesh.v1.SpaceMesh/Generate",'
            'status="OK"}') in text
