"""Automatic repair regions and the growth bound on a real server (tiny exported model, no
mocks): ``{"auto": ...}`` over REST, ``Region.auto_region`` over gRPC, ``max_growth``, and
the new 422 kinds (``region-growth-exceeded``, ``non-orientable``); the SDK's ``auto=``."""

from __future__ import annotations

import json

import grpc
import numpy as np
import pytest
from service_testing import REPAIR_STEPS, mesh_file

from spacemesh.examples import icosphere
from spacemesh.io import load_mesh
from spacemesh.topology import check_topology
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from tests.repair.auto_meshes import moebius, punched, with_fin

pytestmark = pytest.mark.slow

PROBLEM = "https://spacemesh.dev/problems/"
OPEN = punched(icosphere(3), [[0, 0, 1], [0, 0, -1]])


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield pb_grpc.SpaceMeshStub(channel)


def post(http, mesh, region, **params):
    return http.post("/repair", params={"format": "obj", "steps": REPAIR_STEPS, **params},
                     files={"file": ("mesh.obj", mesh_file(mesh, "obj"))},
                     data={"region": json.dumps(region)})


def kept_faces_unchanged(original, out, region_faces: int) -> None:
    """Every input face but the removed ones comes back first, in order, identical."""
    n_kept = original.n_faces - region_faces
    kept_in = {tuple(np.round(original.vertices[f], 6).ravel()) for f in original.faces}
    kept_out = [tuple(np.round(out.vertices[f], 6).ravel()) for f in out.faces[:n_kept]]
    assert set(kept_out) <= kept_in and len(set(kept_out)) == n_kept


def test_auto_holes_over_rest_and_grpc(http, stub):
    response = post(http, OPEN, {"auto": "holes"}, seed=1)
    assert response.status_code == 200, response.text
    h = response.headers
    assert h["x-spacemesh-closed"] == h["x-spacemesh-manifold"] == "true"
    repair = json.loads(h["x-spacemesh-repair"])
    assert repair["auto_region"] == "holes" and repair["findings_total"] == 2
    assert [f["kind"] for f in repair["findings"]] == ["hole", "hole"]
    assert all(f["filled_by"] in ("model", "fallback", "model-and-fallback")
               for f in repair["findings"])
    assert len(repair["regions"]) == 2 and all(  # filled in place: no input face changes
        r["strategy"] == "in-place" and r["requested_faces"] > 0 and r["share"] == 0
        for r in repair["regions"])
    assert repair["region_faces"] == 0
    out = load_mesh(response.content, file_type="obj")
    assert check_topology(out).is_closed_oriented_manifold
    kept_faces_unchanged(OPEN, out, repair["region_faces"])

    reply = stub.Repair(pb.RepairRequest(mesh=mesh_file(OPEN, "obj"), filename="mesh.obj",
                                         region=pb.Region(auto_region="holes"), seed=1,
                                         steps=REPAIR_STEPS, format="obj"))
    assert reply.mesh == response.content  # the same bytes over gRPC
    assert reply.repair.auto_region == "holes" and reply.repair.findings_total == 2
    assert [f.kind for f in reply.repair.findings] == ["hole", "hole"]
    assert [r.share for r in reply.repair.regions] == [r["share"] for r in repair["regions"]]
    assert reply.repair.passes == repair["passes"]


def test_auto_all_rebuilds_a_non_manifold_edge(http):
    mesh = with_fin(icosphere(2))
    refused = post(http, mesh, {"faces": [100]})
    assert refused.status_code == 422
    assert refused.json()["type"] == PROBLEM + "defects-outside-region"
    response = post(http, mesh, {"auto": "all"})
    assert response.status_code == 200, response.text
    repair = json.loads(response.headers["x-spacemesh-repair"])
    assert "non-manifold-edges" in {f["kind"] for f in repair["findings"]}
    assert check_topology(load_mesh(response.content, file_type="obj")
                          ).is_closed_oriented_manifold


def test_problems_of_automatic_regions(http, stub):
    body = post(http, moebius(), {"auto": "holes"}).json()
    assert body["status"] == 422 and body["type"] == PROBLEM + "non-orientable"
    assert "Moebius" in body["detail"] and body["faces"]
    body = post(http, icosphere(2), {"auto": "defects"}).json()
    assert body["type"] == PROBLEM + "empty-region"
    body = post(http, OPEN, {"auto": "everything"}).json()
    assert body["type"] == PROBLEM + "invalid-region"
    with pytest.raises(grpc.RpcError) as info:
        stub.Repair(pb.RepairRequest(mesh=mesh_file(moebius(), "obj"), filename="m.obj",
                                     region=pb.Region(auto_region="all"),
                                     steps=REPAIR_STEPS))
    assert info.value.code() == grpc.StatusCode.FAILED_PRECONDITION
    assert dict(info.value.trailing_metadata())["problem-type"] == PROBLEM + "non-orientable"


def _pinched_pair(mesh):
    around = np.unique(mesh.face_of_corner[mesh.face_indices == 0])
    faces = {int(f): set(mesh.faces[f].tolist()) for f in around}
    return next([a, b] for a in faces for b in faces if a < b and faces[a] & faces[b] == {0})


def test_growth_bound_and_max_growth(http, stub):
    mesh = icosphere(1)  # 80 faces: the pinched pair grows to the 5 faces around vertex 0
    region = {"faces": _pinched_pair(mesh)}
    body = post(http, mesh, region, max_growth=0.05).json()
    assert body["status"] == 422 and body["type"] == PROBLEM + "region-growth-exceeded"
    assert body["share"] == pytest.approx(5 / 80) and body["max_growth"] == 0.05
    response = post(http, mesh, region)  # the default 25 %
    assert response.status_code == 200, response.text
    repair = json.loads(response.headers["x-spacemesh-repair"])
    assert repair["grown_faces"] == 3 and repair["region_share"] == pytest.approx(5 / 80)
    bad = post(http, mesh, region, max_growth=1.5).json()
    assert bad["status"] == 422 and bad["option"] == "max_growth"
    assert bad["type"] == PROBLEM + "invalid-option"
    with pytest.raises(grpc.RpcError) as info:
        stub.Repair(pb.RepairRequest(mesh=mesh_file(mesh, "obj"), filename="m.obj",
                                     faces=region["faces"], max_growth=0.05,
                                     steps=REPAIR_STEPS))
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert dict(info.value.trailing_metadata())["problem-type"] == (
        PROBLEM + "region-growth-exceeded")


@pytest.mark.parametrize("transport", ["rest", "grpc"])
def test_sdk_auto_argument(server, transport):
    from spacemesh_client import Client, RetryPolicy
    from spacemesh_client.errors import NonOrientable, RegionGrowthExceeded

    url = server.url if transport == "rest" else "grpc://" + server.grpc_target
    with Client(url, timeout=60, retry=RetryPolicy.never()) as client:
        mesh = client.repair(mesh_file(OPEN, "obj"), auto="holes", filename="open.obj",
                             steps=REPAIR_STEPS, seed=2, format="obj")
        assert mesh.repair["auto_region"] == "holes" and mesh.repair["findings_total"] == 2
        assert {f["kind"] for f in mesh.repair["findings"]} == {"hole"}
        assert mesh.stats.closed and mesh.stats.manifold and mesh.stats.oriented
        with pytest.raises(NonOrientable):
            client.repair(mesh_file(moebius(), "obj"), auto="all", filename="m.obj",
                          steps=REPAIR_STEPS)
        ico = icosphere(1)
        with pytest.raises(RegionGrowthExceeded) as info:
            client.repair(mesh_file(ico, "obj"), {"faces": _pinched_pair(ico)},
                          filename="m.obj", steps=REPAIR_STEPS, max_growth=0.05)
        assert info.value.extra["share"] == pytest.approx(5 / 80)
        with pytest.raises(TypeError, match="not both"):
            client.repair(mesh_file(OPEN, "obj"), {"faces": [0]}, auto="holes")
