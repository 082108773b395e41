"""Meshes as input to ``POST /generate`` and gRPC ``Generate`` on a real server: a file
whose reader finds faces is sampled on its surface (``X-SpaceMesh-Input: mesh``,
``MeshReply.input_kind``); a point cloud, in any format, stays ``points``."""

from __future__ import annotations

import grpc
import numpy as np
import pytest
from service_testing import UPLOADS, mesh_file

from spacemesh.examples import icosphere
from spacemesh.io.surface import load_cloud_input
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

pytestmark = pytest.mark.slow

LOW_POLY = icosphere(1)  # 42 vertices: read as points it would be far too few


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield pb_grpc.SpaceMeshStub(channel)


@pytest.mark.parametrize("fmt", ["obj", "off", "ply", "stl", "glb"])
def test_a_mesh_upload_is_sampled_on_its_surface(http, stub, case, fmt):
    # the whole default path once; the other formats ask for the network's mesh (raw), as
    # what they test is the reading and sampling, and a mesh's samples make a long fit
    options = {"seed": case.good_seed, "format": "obj"} | ({} if fmt == "obj" else
                                                           {"raw": True})
    data = mesh_file(LOW_POLY, fmt)
    response = http.post("/generate", params=options, files={"file": (f"shape.{fmt}", data)})
    assert response.status_code == 200, response.text
    assert response.headers["x-spacemesh-input"] == "mesh"
    # the same as the points sampled by the shared reader, sent as a cloud
    cloud = load_cloud_input(data, file_type=fmt)
    as_points = http.post("/generate", json={"points": cloud.points.tolist(),
                                             "normals": cloud.normals.tolist(), **options})
    assert as_points.status_code == 200, as_points.text
    assert as_points.headers["x-spacemesh-input"] == "points"
    assert as_points.content == response.content
    reply = stub.Generate(pb.GenerateRequest(
        file=pb.PointCloudFile(data=data, filename=f"shape.{fmt}"), **options))
    assert reply.input_kind == "mesh" and reply.mesh == response.content


def test_point_clouds_stay_points(http, stub, case):
    for name in ("ply", "obj", "xyz"):
        filename, encode = UPLOADS[name]
        response = http.post("/generate", params={"seed": case.good_seed},
                             files={"file": (filename, encode(case.points))})
        assert response.status_code == 200, (name, response.text)
        assert response.headers["x-spacemesh-input"] == "points", name
    reply = stub.Generate(pb.GenerateRequest(
        points=pb.Points(xyz=np.asarray(case.points).ravel().tolist()), seed=case.good_seed))
    assert reply.input_kind == "points"
