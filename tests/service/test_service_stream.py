"""``POST /generate/stream`` and ``/repair/stream`` (Server-Sent Events) on a real server
(uvicorn on loopback, tiny exported model), and the SDK's progress callback over REST."""

from __future__ import annotations

import asyncio
import base64
import json

import pytest
from service_testing import REPAIR_STEPS, WrappedGenerator, as_ply, mesh_file, repair_mesh_cases

from spacemesh_client import AsyncClient, Client, SpaceMeshError

pytestmark = pytest.mark.slow

EVENT_STREAM = "text/event-stream"
PROBLEM = "application/problem+json"
#: Headers that differ between two runs of the same request (timings, batching).
VARYING = {"server-timing", "x-spacemesh-batch-size"}


def read_events(response) -> list[tuple[str, dict]]:
    """The ``(event, data)`` pairs of a Server-Sent Events response, in order."""
    events, name, data = [], None, []
    for line in response.iter_lines():
        if line.startswith(":"):
            continue  # a keep-alive comment
        if not line:
            if name is not None:
                events.append((name, json.loads("\n".join(data))))
            name, data = None, []
        elif line.startswith("event:"):
            name = line[len("event:"):].strip()
        elif line.startswith("data:"):
            data.append(line[len("data:"):].strip())
    assert name is None, "the stream ended inside an event"
    return events


def stream(http, route: str, **kwargs) -> tuple[object, list[tuple[str, dict]]]:
    with http.stream("POST", route, **kwargs) as response:
        if response.headers["content-type"].startswith(EVENT_STREAM):
            return response, read_events(response)
        response.read()
        return response, []


def spacemesh_headers(headers) -> dict[str, str]:
    return {k.lower(): v for k, v in headers.items()
            if k.lower().startswith("x-spacemesh-") and k.lower() not in VARYING}


@pytest.mark.parametrize("start", ["noise", "points"])
def test_progress_comes_before_a_result_equal_to_the_plain_route(http, case, start):
    params = {"seed": case.good_seed, "format": "ply", "start": start, "steps": 6}
    files = {"file": ("cloud.ply", as_ply(case.points))}
    response, events = stream(http, "/generate/stream", params=params, files=files)
    assert response.status_code == 200
    assert response.headers["cache-control"] == "no-cache"
    names = [name for name, _ in events]
    assert names[-1] == "result" and set(names[:-1]) == {"progress"}, names
    progress = [data for _, data in events[:-1]]
    stages = [p["stage"] for p in progress]
    for stage in ("queued", "encoder", "sampler", "connectivity", "decode", "geometry",
                  "report", "encode_output"):
        assert stage in stages, stages
    assert stages[0] == "queued" and stages[-1] == "encode_output"
    assert stages.index("encoder") < stages.index("sampler") < stages.index("connectivity")
    steps = [p for p in progress if p["stage"] == "sampler" and p["done"] >= 1]
    fractions = [p["fraction"] for p in progress]
    assert fractions == sorted(fractions) and 0 < fractions[0] and fractions[-1] < 1

    result = events[-1][1]
    plain = http.post("/generate", params=params, files=files)
    assert plain.status_code == 200, plain.text
    assert base64.b64decode(result["body"]) == plain.content  # byte for byte
    assert result["format"] == "ply"
    assert result["media_type"] == plain.headers["content-type"]
    assert f'filename="{result["filename"]}"' in plain.headers["content-disposition"]
    assert spacemesh_headers(result["headers"]) == spacemesh_headers(plain.headers)
    # the sampler begins with 0 of its steps done, then one event per diffusion step
    begin = next(p for p in progress if p["stage"] == "sampler")
    assert begin["done"] == 0 and begin["total"] <= int(plain.headers["x-spacemesh-steps"])
    assert [p["done"] for p in steps] == list(range(1, begin["total"] + 1))


class BrokenAfterStart(WrappedGenerator):
    """The real generator, failing (a bug) as the connectivity stage of a streamed
    request begins (the warm-up, which reports no stages, passes)."""

    def generate_batch(self, requests, *, progress=None, stage=None):
        def failing(name: str, done: int, total: int) -> None:
            if name == "connectivity":
                raise RuntimeError("a bug in the connectivity stage")
            stage(name, done, total)

        return self.inner.generate_batch(requests, progress=progress,
                                         stage=None if stage is None else failing)


@pytest.fixture(scope="module")
def broken_http(start_server, generator):
    import httpx

    server = start_server(BrokenAfterStart(generator))
    with httpx.Client(base_url=server.url, timeout=60) as client:
        yield client


def test_an_error_after_the_start_is_a_problem_event(broken_http, case):
    files = {"file": ("cloud.ply", as_ply(case.points))}
    response, events = stream(broken_http, "/generate/stream",
                              params={"seed": case.good_seed}, files=files)
    assert response.status_code == 200, response.text
    names = [name for name, _ in events]
    assert names[-1] == "problem" and set(names[:-1]) == {"progress"}, names
    stages = [data["stage"] for _, data in events[:-1]]
    assert stages[0] == "queued" and "encoder" in stages and "connectivity" not in stages
    problem = events[-1][1]
    assert problem["type"] == "https://spacemesh.dev/problems/internal-error", problem
    assert problem["status"] == 500 and problem["detail"]
    assert problem["instance"] == "/generate/stream"
    assert "bug" not in json.dumps(problem)  # no internals leak, as for the plain route
    with Client(str(broken_http.base_url)) as client, pytest.raises(SpaceMeshError) as error:
        client.generate(case.points, seed=case.good_seed, progress=lambda d, t: None)
    assert error.value.status == 500


def test_no_surface_after_the_start_is_a_problem_event(http, case):
    files = {"file": ("cloud.ply", as_ply(case.points))}
    _, events = stream(http, "/generate/stream", params=case.no_surface, files=files)
    assert [name for name, _ in events][-1] == "problem"
    problem = events[-1][1]
    assert problem["type"] == "https://spacemesh.dev/problems/no-surface", problem
    assert problem["status"] == 422 and problem["seed"] == case.no_surface["seed"]


def test_an_error_before_the_start_is_a_plain_problem(http, case):
    cases = [
        (dict(files={"file": ("cloud.ply", b"ply\nthis is not a ply file\n")}), 400),
        (dict(params={"steps": 0}, files={"file": ("cloud.ply", as_ply(case.points))}), 422),
        (dict(content=b"points", headers={"content-type": "text/plain"}), 415),
    ]
    for kwargs, status in cases:
        response, events = stream(http, "/generate/stream", **kwargs)
        assert events == [] and response.status_code == status, response.text
        assert response.headers["content-type"].startswith(PROBLEM)
        assert response.json()["instance"] == "/generate/stream"


def test_repair_streams_its_steps_and_the_plain_result(http):
    mesh, region = repair_mesh_cases()["faces"]
    kwargs = dict(params={"format": "obj", "steps": REPAIR_STEPS, "seed": 3},
                  files={"file": ("mesh.obj", mesh_file(mesh, "obj"))},
                  data={"region": json.dumps(region)})
    response, events = stream(http, "/repair/stream", **kwargs)
    assert response.status_code == 200
    assert [name for name, _ in events][-1] == "result"
    stages = [data["stage"] for name, data in events if name == "progress"]
    assert stages[0] == "queued" and stages[-1] == "encode_output"
    assert stages.count("sampler") >= 1
    plain = http.post("/repair", **kwargs)
    assert plain.status_code == 200, plain.text
    result = events[-1][1]
    assert base64.b64decode(result["body"]) == plain.content
    assert spacemesh_headers(result["headers"]) == spacemesh_headers(plain.headers)
    bad = {**kwargs, "data": {"region": json.dumps({"faces": [10**6]})}}
    response, events = stream(http, "/repair/stream", **bad)
    assert events == [] and response.status_code == 422
    assert response.headers["content-type"].startswith(PROBLEM)


def test_sdk_progress_over_rest(server, case):
    options = dict(seed=case.good_seed, steps=5, start="noise")
    seen: list[tuple[int, int]] = []
    with Client(server.url) as client:
        mesh = client.generate(case.points, **options,
                               progress=lambda d, t: seen.append((d, t)))
        plain = client.generate(case.points, **options)
    assert seen == [(i, 5) for i in range(1, 6)]
    assert mesh.data == plain.data and mesh.stats == plain.stats
    assert mesh.seed == plain.seed == case.good_seed and mesh.options == plain.options

    async def run() -> tuple[list, object]:
        steps: list[tuple[int, int]] = []
        async with AsyncClient(server.url) as client:
            result = await client.generate(case.points, **options,
                                           progress=lambda d, t: steps.append((d, t)))
        return steps, result

    steps, result = asyncio.run(run())
    assert steps == seen and result.data == plain.data


def test_grpc_generate_stream_reports_the_stages_of_the_sse_stream(http, server, case):
    import grpc

    from spacemesh_service.pb import spacemesh_pb2 as pb
    from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

    params = {"seed": case.good_seed, "format": "ply", "start": "noise", "steps": 4}
    _, events = stream(http, "/generate/stream", params=params,
                       files={"file": ("cloud.ply", as_ply(case.points))})
    sse = [(d["stage"], d["done"], d["total"], d["fraction"]) for n, d in events[:-1]]
    with grpc.insecure_channel(server.grpc_target) as channel:
        replies = list(pb_grpc.SpaceMeshStub(channel).GenerateStream(pb.GenerateRequest(
            file=pb.PointCloudFile(data=as_ply(case.points), filename="cloud.ply"),
            stages=True, **params)))
    kinds = [r.WhichOneof("event") for r in replies]
    assert kinds[-1] == "mesh" and set(kinds[:-1]) == {"progress"}, kinds
    over_grpc = [(r.progress.stage, r.progress.step, r.progress.total, r.progress.fraction)
                 for r in replies[:-1]]
    stages = [p[0] for p in over_grpc]
    for stage in ("queued", "encoder", "sampler", "connectivity", "geometry",
                  "encode_output"):
        assert stage in stages, stages
    assert over_grpc == sse  # the same events as the SSE stream, in the same order
    assert replies[-1].mesh.mesh == base64.b64decode(events[-1][1]["body"])
