"""The per-request budget on real servers: a request estimated over it is answered 422
``too-expensive`` naming the option to lower, over REST and gRPC, before any work is
queued; the default budget (twice the request deadline) admits real work on the shipped
model and refuses issue 37's reproductions. No test asserts a timing."""

from __future__ import annotations

import json

import grpc
import httpx
import pytest
from service_testing import REPAIR_STEPS, mesh_file, metric

from spacemesh.examples import icosphere
from spacemesh.runtime.budget import CostError
from spacemesh.runtime.cost import DEFAULT_COST_MODEL
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.repository import default_model_dir, resolve_version_dir
from spacemesh.runtime.spec import ModelSpec
from spacemesh_service import problems as P
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from spacemesh_service.settings import Settings

pytestmark = pytest.mark.slow

#: Issue 37's first reproduction (on 200,000 points), and its second (the example cloud).
HEAVY = {"samples": 16, "target_vertices": 10_000, "steps": 1024, "start": "points",
         "start_time": 1.0}
EXAMPLE_HEAVY = {"target_vertices": 10_000}
#: A budget (s) the tiny model's default request fits and a 10,000-vertex one does not.
SMALL_BUDGET_S = 5.0


@pytest.fixture(scope="module")
def budgeted(start_server, generator):
    """A server whose budget is :data:`SMALL_BUDGET_S` seconds."""
    return start_server(generator, warmup=False, request_budget_s=SMALL_BUDGET_S)


# ---------------------------------------------------------------------- the default
def shipped_spec() -> ModelSpec:
    folder = default_model_dir()
    if not folder.exists():
        pytest.skip("no shipped model in this checkout")
    return ModelSpec.from_manifest(json.loads(
        (resolve_version_dir(folder) / "manifest.json").read_text()))


def test_the_default_budget_admits_real_work_and_refuses_issue_37():
    settings = Settings()
    spec, budget = shipped_spec(), settings.budget
    assert budget.seconds == 2 * settings.request_timeout_s
    assert budget.memory_mb == settings.request_budget_mb

    def estimate(points, **options):
        return DEFAULT_COST_MODEL.generate(spec, GenerateOptions(**options).resolve(spec),
                                           points)

    budget.check(estimate(settings.working_points, target_vertices=2048, samples=4))
    for points, options in ((settings.working_points, HEAVY), (2048, EXAMPLE_HEAVY)):
        with pytest.raises(CostError) as info:
            budget.check(estimate(points, **options), what="generate")
        assert info.value.option == "target_vertices", str(info.value)


def test_the_budget_settings_have_flags_and_variables():
    env = {"SPACEMESH_REQUEST_BUDGET_S": "12.5", "SPACEMESH_REQUEST_BUDGET_MB": "512"}
    settings = Settings.from_env(env)
    assert (settings.budget.seconds, settings.budget.memory_mb) == (12.5, 512.0)
    assert Settings.from_env({}, request_timeout_s=10).budget.seconds == 20.0
    assert Settings.from_env(env, request_budget_s=3).budget.seconds == 3.0  # flag wins
    with pytest.raises(ValueError, match="SPACEMESH_REQUEST_BUDGET_MB"):
        Settings.from_env({"SPACEMESH_REQUEST_BUDGET_MB": "0"})


# ---------------------------------------------------------------------- on a server
def test_over_budget_is_422_naming_the_option_before_any_work(budgeted, case):
    url = budgeted.url
    assert metric(url, "spacemesh_batches_total") == 0
    body = {"points": case.points.tolist(), "start": "points", "target_vertices": 10_000}
    response = httpx.post(url + "/generate", json=body, timeout=60)
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith(P.PROBLEM_MEDIA_TYPE)
    problem = response.json()
    assert problem["type"] == P.TOO_EXPENSIVE.type and problem["option"] == "target_vertices"
    assert "lower target_vertices" in problem["detail"]
    assert problem["estimated_seconds"] > problem["budget_seconds"] == SMALL_BUDGET_S
    fits = problem["suggestion"]["target_vertices"]
    assert 4 <= fits < 10_000 and f"target_vertices={fits} fits" in problem["detail"]
    # nothing was queued or run: no batch, no queue wait; counted as too expensive
    assert metric(url, "spacemesh_batches_total") == 0
    assert metric(url, 'spacemesh_stage_seconds_count{stage="queue"}') == 0
    assert metric(url, 'spacemesh_too_expensive_total{option="target_vertices",'
                       'route="generate"}') == 1
    # the suggested value is admitted, and then a batch runs
    ok = httpx.post(url + "/generate", json={**body, "target_vertices": 60,
                                             "seed": case.good_seed}, timeout=60)
    assert ok.status_code == 200, ok.text
    assert metric(url, "spacemesh_batches_total") == 1


def test_the_option_named_is_the_one_that_costs_most(budgeted, case):
    body = {"points": case.points.tolist(), "start": "points", "samples": 16,
            "target_vertices": 1000}
    problem = httpx.post(budgeted.url + "/generate", json=body, timeout=60).json()
    assert problem["type"] == P.TOO_EXPENSIVE.type and problem["option"] == "samples"
    savings = problem["savings"]
    assert savings["samples"]["seconds"] == max(s["seconds"] for s in savings.values())
    # the stream answers the same problem before its stream starts
    stream = httpx.post(budgeted.url + "/generate/stream", json=body, timeout=60)
    assert stream.status_code == 422 and stream.json()["option"] == "samples"


def test_grpc_maps_too_expensive_like_an_option_error(budgeted, case):
    request = pb.GenerateRequest(points=pb.Points(xyz=case.points.ravel().tolist()),
                                 start="points", target_vertices=10_000)
    with grpc.insecure_channel(budgeted.grpc_target) as channel:
        stub = pb_grpc.SpaceMeshStub(channel)
        with pytest.raises(grpc.RpcError) as info:
            stub.Generate(request)
    error = info.value
    assert error.code() == P.INVALID_OPTION.grpc_code == grpc.StatusCode.INVALID_ARGUMENT
    metadata = dict(error.trailing_metadata())
    assert metadata["problem-type"] == P.TOO_EXPENSIVE.type
    assert metadata["problem-status"] == "422"
    assert json.loads(metadata["problem-extensions"])["option"] == "target_vertices"
    assert "lower target_vertices" in error.details()


def test_a_repair_over_budget_is_refused_before_it_is_queued(start_server, generator):
    server = start_server(generator, warmup=False, request_budget_s=0.5)
    mesh = icosphere(2)
    response = httpx.post(server.url + "/repair", params={"format": "obj", "steps": 64},
                          files={"file": ("mesh.obj", mesh_file(mesh))},
                          data={"region": json.dumps({"faces": [0, 1]})}, timeout=60)
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"] == P.TOO_EXPENSIVE.type and problem["option"] == "steps"
    assert "this repair is estimated" in problem["detail"]
    assert metric(server.url, "spacemesh_batches_total") == 0
    assert metric(server.url, 'spacemesh_too_expensive_total{option="steps",'
                              'route="repair"}') == 1
    with grpc.insecure_channel(server.grpc_target) as channel:
        with pytest.raises(grpc.RpcError) as info:
            pb_grpc.SpaceMeshStub(channel).Repair(pb.RepairRequest(
                mesh=mesh_file(mesh), filename="mesh.obj", faces=[0, 1], steps=64))
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert dict(info.value.trailing_metadata())["problem-type"] == P.TOO_EXPENSIVE.type
    assert REPAIR_STEPS < 64  # the other repair tests stay within their budget


def test_the_budget_is_in_the_metadata_and_openapi(budgeted, http):
    limits = httpx.get(budgeted.url + "/v2/models/spacemesh-tiny").json()["limits"]
    assert limits["request_budget_s"] == SMALL_BUDGET_S
    assert limits["request_budget_mb"] == Settings().request_budget_mb
    spec = http.get("/openapi.json").json()
    for route in ("/generate", "/repair"):
        examples = spec["paths"][route]["post"]["responses"]["422"]["content"][
            P.PROBLEM_MEDIA_TYPE]["examples"]
        assert examples["expensive"]["value"]["type"] == P.TOO_EXPENSIVE.type, route
