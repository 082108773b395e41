"""Uploads are bounded before they are parsed: bombs get 413 over REST and gRPC, and at
most ``max_parallel_parses`` parses run at once (even when their requests are cancelled)."""

from __future__ import annotations

import asyncio
import threading

import grpc
import numpy as np
import pytest

from spacemesh_service.inputs import ParseSlots
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from tests.io.bombs import BOMBS, inflating_npz, json_points, xyz_lines

TOO_LARGE = {"too-many-points", "payload-too-large"}
TYPE = "https://spacemesh.dev/problems/"
MESH_TYPES = ("ply", "off", "stl", "glb", "gltf")
#: Every upload that must be refused: the bombs, a real inflating archive, too many rows.
UPLOAD_BOMBS = {
    **BOMBS,
    "npz-inflating": ("npz", inflating_npz(1_000_000)),
    "xyz-rows": ("xyz", xyz_lines(100_000)),
}


def assert_too_large(response) -> dict:
    assert response.status_code == 413, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    body = response.json()
    assert body["type"].removeprefix(TYPE) in TOO_LARGE and body["limit"] > 0, body
    return body


def assert_rpc_too_large(call) -> None:
    with pytest.raises(grpc.RpcError) as info:
        call()
    assert info.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED, info.value.details()
    metadata = dict(info.value.trailing_metadata() or ())
    assert metadata["problem-type"].removeprefix(TYPE) in TOO_LARGE, metadata


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield pb_grpc.SpaceMeshStub(channel)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(UPLOAD_BOMBS))
def test_a_bomb_upload_is_413_over_rest_and_grpc(http, stub, name):
    file_type, data = UPLOAD_BOMBS[name]
    filename = f"bomb.{file_type}"
    assert_too_large(http.post("/generate", files={"file": (filename, data)}))
    request = pb.GenerateRequest(file=pb.PointCloudFile(data=data, filename=filename))
    assert_rpc_too_large(lambda: stub.Generate(request))
    if file_type in MESH_TYPES:
        assert_too_large(http.post("/repair", files={"file": (filename, data)},
                                   data={"region": '{"faces": [0]}'}))
        repair = pb.RepairRequest(mesh=data, filename=filename, faces=[0])
        assert_rpc_too_large(lambda: stub.Repair(repair))


@pytest.mark.slow
def test_json_and_numbers_over_the_limits_are_413(http, stub):
    body = assert_too_large(http.post("/generate", content=json_points(20_000),
                                      headers={"content-type": "application/json"}))
    assert body["what"] == "values"  # counted before any is parsed
    xyz = np.zeros(3 * 5_001).tolist()
    assert_rpc_too_large(lambda: stub.Generate(pb.GenerateRequest(points=pb.Points(xyz=xyz))))


def test_parse_slots_bound_the_parses_alive_even_when_cancelled():
    slots = ParseSlots(2)
    release = threading.Event()
    lock = threading.Lock()
    alive = [0, 0]  # now, most

    def parse() -> int:
        with lock:
            alive[0] += 1
            alive[1] = max(alive[1], alive[0])
        release.wait(10)
        with lock:
            alive[0] -= 1
        return 7

    async def scenario() -> list:
        tasks = [asyncio.ensure_future(slots.run(parse)) for _ in range(6)]
        while slots.running < 2:
            await asyncio.sleep(0.01)
        for task in tasks[:3]:  # two running, one waiting: cancelled
            task.cancel()
        await asyncio.sleep(0.05)
        assert slots.running == 2  # the cancelled parses still hold their slots
        release.set()
        results = await asyncio.gather(*tasks, return_exceptions=True)
        while slots.running:
            await asyncio.sleep(0.01)
        return results

    results = asyncio.run(scenario())
    assert alive[1] == 2
    assert [isinstance(r, asyncio.CancelledError) for r in results] == [True] * 3 + [False] * 3
    assert results[3:] == [7, 7, 7]
