"""The server's repair check: the faces a repair changed are exactly the grown region's.

A repair whose output changed a face outside the region (a moved corner, or a kept face
re-generated) is still a closed oriented manifold, so the mesh validation alone would
send it. :func:`spacemesh.repair.verify_repair` refuses it, and the server answers
``invalid-output`` (500, gRPC INTERNAL) instead of the mesh.
"""

from __future__ import annotations

import json

import grpc
import httpx
import numpy as np
import pytest
from service_testing import REPAIR_STEPS, faulty_repair, mesh_file, repair_mesh_cases

from spacemesh.repair import plan_repair, repair_mesh, verify_repair
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

pytestmark = pytest.mark.slow

MESH, REGION = repair_mesh_cases()["faces"]
INVALID_OUTPUT = "https://spacemesh.dev/problems/invalid-output"


def test_verify_repair_accepts_a_real_repair_and_names_each_fault(generator):
    plan = plan_repair(MESH, REGION, generator.spec.max_vertices)
    result = repair_mesh(MESH, REGION, generator, steps=REPAIR_STEPS, plan=plan)
    assert verify_repair(plan, result) == []
    for fault, words in (("moved", "changed"), ("dropped", "not the")):
        bad = faulty_repair(repair_mesh, fault)(MESH, REGION, generator, steps=REPAIR_STEPS,
                                                plan=plan)
        issues = verify_repair(plan, bad)
        assert len(issues) == 1 and words in issues[0], (fault, issues)
    # a region face reported as kept: the changed faces are not the grown region's
    inside = int(np.flatnonzero(plan.cut.region)[0])
    source = result.face_source.copy()
    source[-1] = inside
    assert verify_repair(plan, type(result)(result.mesh, result.vertex_map, source,
                                            result.region, result.stats))


@pytest.mark.parametrize("fault", ["moved", "dropped"])
def test_a_repair_that_changes_a_face_outside_the_region_is_refused(
        start_server, generator, monkeypatch, fault):
    import spacemesh_service.engine as engine_module

    monkeypatch.setattr(engine_module, "repair_mesh", faulty_repair(repair_mesh, fault))
    server = start_server(generator, warmup=False)
    body = mesh_file(MESH)
    response = httpx.post(server.url + "/repair", params={"format": "obj",
                                                          "steps": REPAIR_STEPS},
                          files={"file": ("mesh.obj", body)},
                          data={"region": json.dumps(REGION)}, timeout=60)
    assert response.status_code == 500, response.text
    problem = response.json()
    assert problem["type"] == INVALID_OUTPUT
    assert "outside the grown region" in problem["detail"]
    request = pb.RepairRequest(mesh=body, filename="mesh.obj", faces=REGION["faces"],
                               steps=REPAIR_STEPS, format="obj")
    with grpc.insecure_channel(server.grpc_target) as channel:
        with pytest.raises(grpc.RpcError) as info:
            pb_grpc.SpaceMeshStub(channel).Repair(request)
    assert info.value.code() == grpc.StatusCode.INTERNAL
    assert dict(info.value.trailing_metadata())["problem-type"] == INVALID_OUTPUT
    assert info.value.details() == problem["detail"]
