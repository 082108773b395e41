"""``POST /repair`` and gRPC ``Repair`` on a real server (tiny exported model, no mocks):
every region form, every output format, seed replay, REST/gRPC parity, and every error."""

from __future__ import annotations

import json
import re

import grpc
import numpy as np
import pytest
from service_testing import (
    REPAIR_STEPS,
    as_ply,
    check_repair,
    make_cloud,
    mesh_file,
    region_pb,
    repair_mesh_cases,
)

from spacemesh.examples import icosphere
from spacemesh.io import load_mesh
from spacemesh.mesh import PolygonMesh
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from tests.repair.repair_testing import flat_shaded
from tests.repair.test_repair_cut import open_icosphere, with_fin

pytestmark = pytest.mark.slow

PROBLEM = "application/problem+json"
CASES = repair_mesh_cases()
SEED = 3


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield pb_grpc.SpaceMeshStub(channel)


def post_repair(http, mesh, region, *, fmt: str = "obj", filename: str = "mesh.obj",
                data: bytes | None = None, **params):
    """``POST /repair`` with the mesh as ``file`` and the region (JSON) as ``region``."""
    body = mesh_file(mesh, filename.rsplit(".", 1)[-1]) if data is None else data
    form = {"region": region if isinstance(region, str) else json.dumps(region)}
    return http.post("/repair", params={"format": fmt, "steps": REPAIR_STEPS, **params},
                     files={"file": (filename, body)}, data=form)


def assert_problem(response, status: int, slug: str) -> dict:
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith(PROBLEM)
    body = response.json()
    assert body["type"] == f"https://spacemesh.dev/problems/{slug}", body
    assert body["status"] == status and body["title"] and body["detail"]
    assert body["instance"] == "/repair"
    return body


def repair_pb(mesh, region: dict | None = None, **fields) -> pb.RepairRequest:
    fields.setdefault("steps", REPAIR_STEPS)
    if region is not None:
        fields["region"] = region_pb(region)
    return pb.RepairRequest(mesh=mesh_file(mesh), filename="mesh.obj", **fields)


def assert_rpc_problem(call, code: grpc.StatusCode, slug: str) -> dict[str, str]:
    with pytest.raises(grpc.RpcError) as info:
        call()
    assert info.value.code() == code, info.value.details()
    metadata = dict(info.value.trailing_metadata() or ())
    assert metadata["problem-type"] == f"https://spacemesh.dev/problems/{slug}"
    return metadata


# ---------------------------------------------------------------------- region forms
@pytest.mark.parametrize("form", sorted(CASES))
def test_every_region_form_over_rest_and_grpc(http, stub, form):
    mesh, region = CASES[form]
    response = post_repair(http, mesh, region, seed=SEED)
    assert response.status_code == 200, response.text
    h = response.headers
    assert h["content-type"] == "model/obj"
    assert h["x-spacemesh-closed"] == h["x-spacemesh-manifold"] == h["x-spacemesh-oriented"] == (
        "true")
    assert h["x-spacemesh-seed"] == str(SEED) and h["x-spacemesh-steps"] == str(REPAIR_STEPS)
    assert h["x-spacemesh-batch-size"] == "1"
    repair = json.loads(h["x-spacemesh-repair"])
    assert h["x-spacemesh-region-faces"] == str(repair["region_faces"])
    assert h["x-spacemesh-new-faces"] == str(repair["new_faces"])
    assert h["x-spacemesh-fallback"] == repair["fallback"]
    assert h["x-spacemesh-welded-vertices"] == "0" == str(repair["welded_vertices"])
    assert {"cut", "patch", "encoder", "sampler", "connectivity", "splice",
            "encode_output"} <= {part.split(";")[0].strip()
                                 for part in h["server-timing"].split(",")}
    out = load_mesh(response.content, file_type="obj")
    check_repair(mesh, region, out.vertices, out.faces, repair)
    assert int(h["x-spacemesh-faces"]) == out.n_faces

    reply = stub.Repair(repair_pb(mesh, region, seed=SEED, format="obj"))
    assert reply.mesh == response.content  # the same bytes over gRPC
    assert reply.seed == SEED and reply.steps == REPAIR_STEPS and reply.batch_size == 1
    assert reply.stats.closed and reply.stats.faces == out.n_faces
    assert reply.repair.region_faces == repair["region_faces"]
    assert reply.repair.fallback == repair["fallback"]
    assert dict(reply.repair.new_face_degrees) == {
        int(k): v for k, v in repair["new_face_degrees"].items()}
    assert {"decode_input", "queue", "cut", "sampler", "splice", "total"} <= set(reply.timings)


def test_grpc_faces_shorthand_is_the_faces_region(stub):
    mesh, region = CASES["faces"]
    by_region = stub.Repair(repair_pb(mesh, region, seed=SEED))
    by_faces = stub.Repair(repair_pb(mesh, faces=region["faces"], seed=SEED))
    assert by_faces.mesh == by_region.mesh and by_faces.format == "glb"


# ---------------------------------------------------------------------- formats, seeds
@pytest.mark.parametrize("fmt", ["glb", "gltf", "obj", "ply", "off", "json"])
def test_every_output_format(http, fmt):
    mesh, region = CASES["faces"]  # triangles: GLB/glTF keep the kept faces too
    response = post_repair(http, mesh, region, fmt=fmt, seed=SEED)
    assert response.status_code == 200, response.text
    media = {"glb": "model/gltf-binary", "gltf": "model/gltf+json", "obj": "model/obj",
             "ply": "model/x-ply", "off": "model/x-off", "json": "application/json"}[fmt]
    assert response.headers["content-type"] == media
    assert f'spacemesh-repair-{SEED}.{fmt}"' in response.headers["content-disposition"]
    repair = json.loads(response.headers["x-spacemesh-repair"])
    if fmt == "json":
        body = response.json()
        vertices, faces = body["vertices"], body["faces"]
        assert body["repair"] == repair and body["seed"] == SEED
        assert body["steps"] == REPAIR_STEPS and body["stats"]["closed"] is True
    else:
        out = load_mesh(response.content, file_type=fmt)
        vertices, faces = out.vertices, out.faces
    check_repair(mesh, region, vertices, faces, repair, polygons=fmt not in ("glb", "gltf"))


def test_every_input_format_is_read(http):
    mesh, region = CASES["sphere"]
    reference = post_repair(http, mesh, region, seed=SEED)
    assert reference.status_code == 200, reference.text
    for fmt in ("off", "ply", "stl", "glb", "gltf"):
        response = post_repair(http, mesh, region, seed=SEED, filename=f"mesh.{fmt}")
        assert response.status_code == 200, (fmt, response.text)
        out = load_mesh(response.content, file_type="obj")
        check_repair(mesh, region, out.vertices, out.faces,
                     json.loads(response.headers["x-spacemesh-repair"]))
    sniffed = post_repair(http, mesh, region, seed=SEED, filename="upload",
                          data=mesh_file(mesh, "ply"))
    assert sniffed.content == reference.content


def test_seed_replays_and_options_as_form_fields(http):
    mesh, region = CASES["box"]
    first = post_repair(http, mesh, region, fmt="ply")
    assert first.status_code == 200, first.text
    seed = int(first.headers["x-spacemesh-seed"])  # picked by the server
    again = post_repair(http, mesh, region, fmt="ply", seed=seed)
    assert again.content == first.content
    form = http.post("/repair", files={"file": ("m.obj", mesh_file(mesh))},
                     data={"region": json.dumps(region), "seed": str(seed), "format": "ply",
                           "steps": str(REPAIR_STEPS)}, params={"seed": 999})
    assert form.status_code == 200 and form.content == first.content  # the form wins
    region_file = http.post("/repair", params={"seed": seed, "format": "ply",
                                               "steps": REPAIR_STEPS},
                            files={"file": ("m.obj", mesh_file(mesh)),
                                   "region": ("region.json", json.dumps(region).encode())})
    assert region_file.content == first.content  # curl -F region=@region.json


def test_open_and_non_manifold_meshes_are_repaired_when_the_region_covers_the_defect(http):
    opened, _ = open_icosphere()
    finned, u = with_fin()
    for mesh, region in ((opened, {"sphere": {"center": opened.vertices[0].tolist(),
                                              "radius": 0.35}}),
                         (finned, {"sphere": {"center": finned.vertices[u].tolist(),
                                              "radius": 0.4}})):
        response = post_repair(http, mesh, region, seed=SEED, filename="mesh.off")
        assert response.status_code == 200, response.text
        out = load_mesh(response.content, file_type="obj")
        check_repair(mesh, region, out.vertices, out.faces,
                     json.loads(response.headers["x-spacemesh-repair"]))


# ---------------------------------------------------------------------- errors
def test_region_errors_are_422_with_their_kind(http, stub):
    mesh = CASES["faces"][0]
    far = {"sphere": {"center": [10.0, 10.0, 10.0], "radius": 0.5}}
    assert_problem(post_repair(http, mesh, far), 422, "empty-region")
    assert_problem(post_repair(http, mesh, {"faces": []}), 422, "empty-region")
    whole = {"box": {"min": [-2, -2, -2], "max": [2, 2, 2]}}
    assert_problem(post_repair(http, mesh, whole), 422, "whole-mesh-region")
    for bad in ({"sphere": {"center": [0, 0], "radius": 1}},
                {"sphere": {"center": [0, 0, 1], "radius": -1}},
                {"faces": [0], "vertices": [1]}, {"cylinder": {}}, [1, 2], {"faces": [1.5]},
                {"faces": [100_000]}, {"box": {"min": [1, 1, 1], "max": [0, 0, 0]}}):
        body = assert_problem(post_repair(http, mesh, bad), 422, "invalid-region")
        assert body["detail"], bad
    large = icosphere(3)  # a band whose boundary needs more than the 64 tokens
    body = assert_problem(post_repair(http, large, {"box": {"min": [-1, -1, -0.1],
                                                            "max": [1, 1, 0.1]}}),
                          422, "region-too-large")
    assert body["boundary_vertices"] > body["max_boundary_vertices"]

    rpc = grpc.StatusCode
    assert_rpc_problem(lambda: stub.Repair(repair_pb(mesh, far)), rpc.INVALID_ARGUMENT,
                       "empty-region")
    assert_rpc_problem(lambda: stub.Repair(repair_pb(mesh, whole)), rpc.INVALID_ARGUMENT,
                       "whole-mesh-region")
    assert_rpc_problem(lambda: stub.Repair(repair_pb(mesh, {"sphere": {
        "center": [0, 0], "radius": 1}})), rpc.INVALID_ARGUMENT, "invalid-region")
    assert_rpc_problem(lambda: stub.Repair(repair_pb(mesh, {"faces": [1]}, faces=[1])),
                       rpc.INVALID_ARGUMENT, "invalid-region")


def test_regions_with_nothing_to_sample_or_huge_indices_are_422(http, stub):
    """Once 500s: a region of a two-vertex face (an IndexError while sampling), a region
    of zero-area faces cut off from the rest (numpy's "high <= 0" as invalid-parameter),
    and a face index of 1e300 (reported as -9223372036854775808)."""
    sphere = icosphere(1)
    n = sphere.n_faces
    two = PolygonMesh.from_faces(sphere.vertices, [*sphere.faces, np.array([0, 1])])
    flat = [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]]  # a tetrahedron of four equal points
    dust = PolygonMesh.from_faces(np.vstack([sphere.vertices, np.full((4, 3), 3.0)]),
                                  [*sphere.faces, *(np.array(f) + 42 for f in flat)])
    cases = ((two, {"faces": [n]}, "face 80 has 2 vertices"),
             (dust, {"faces": [n, n + 1, n + 2, n + 3]}, "no area"))
    for mesh, region, words in cases:
        body = assert_problem(post_repair(http, mesh, region), 422, "invalid-region")
        assert words in body["detail"] and "no boundary" in body["detail"]
        with pytest.raises(grpc.RpcError) as info:
            stub.Repair(repair_pb(mesh, region))
        assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        assert info.value.details() == body["detail"]
    body = assert_problem(post_repair(http, sphere, '{"faces": [1e300]}'), 422,
                          "invalid-region")
    assert body["detail"] == "region faces: index 1e+300 is out of range"
    body = assert_problem(post_repair(http, sphere, '{"vertices": [18446744073709551615]}'),
                          422, "invalid-region")
    assert "18446744073709551615 is out of range" in body["detail"]


def test_defects_outside_the_region_are_422_and_listed(http, stub):
    for mesh, word in ((open_icosphere()[0], "open-boundary"),
                       (with_fin()[0], "non-manifold-edges")):
        away = {"sphere": {"center": (-mesh.vertices[0]).tolist(), "radius": 0.3}}
        body = assert_problem(post_repair(http, mesh, away, filename="mesh.off"), 422,
                              "defects-outside-region")
        assert word in {d["kind"] for d in body["defects"]}
        metadata = assert_rpc_problem(lambda m=mesh, r=away: stub.Repair(repair_pb(m, r)),
                                      grpc.StatusCode.FAILED_PRECONDITION,
                                      "defects-outside-region")
        assert json.loads(metadata["problem-extensions"])["defects"] == body["defects"]


def test_malformed_requests_are_400(http, stub):
    mesh, region = CASES["faces"]
    off = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"  # a face on a missing vertex
    body = assert_problem(post_repair(http, mesh, region, data=off, filename="bad.off"), 400,
                          "malformed-input")
    assert "vertex" in body["detail"]
    assert_problem(post_repair(http, mesh, region, data=b"", filename="m.obj"), 400,
                   "malformed-input")
    cloud = as_ply(make_cloud(50))  # a point cloud: no faces
    assert "no faces" in assert_problem(post_repair(http, mesh, region, data=cloud,
                                                    filename="c.ply"), 400,
                                        "malformed-input")["detail"]
    assert_problem(post_repair(http, mesh, "{not json"), 400, "malformed-input")
    assert_problem(post_repair(http, mesh, ""), 400, "malformed-input")
    no_region = http.post("/repair", files={"file": ("m.obj", mesh_file(mesh))})
    assert "'region'" in assert_problem(no_region, 400, "malformed-input")["detail"]
    no_file = http.post("/repair", files={"other": ("m.obj", b"x")},
                        data={"region": json.dumps(region)})
    assert "'file'" in assert_problem(no_file, 400, "malformed-input")["detail"]
    assert assert_problem(post_repair(http, mesh, region, steps=0), 422,
                          "invalid-option")["option"] == "steps"
    assert assert_problem(post_repair(http, mesh, region, sampler="euler"), 422,
                          "invalid-option")["option"] == "sampler"
    assert assert_problem(post_repair(http, mesh, region, fmt="stl"), 422,
                          "invalid-option")["option"] == "format"
    nan = b"v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"
    assert_problem(post_repair(http, mesh, region, data=nan), 422, "non-finite")
    junk = post_repair(http, mesh, region, data=bytes(range(256)) * 8, filename="m.docx")
    assert_problem(junk, 415, "unsupported-format")
    assert_problem(http.post("/repair", json={"region": region}), 415, "unsupported-format")
    big = post_repair(http, mesh, region, data=b"v 0 0 0\n" * 300_000)  # 2.4 MB > 2 MB
    assert_problem(big, 413, "payload-too-large")

    rpc = grpc.StatusCode
    assert_rpc_problem(lambda: stub.Repair(pb.RepairRequest(mesh=mesh_file(mesh))),
                       rpc.INVALID_ARGUMENT, "malformed-input")  # no region
    assert_rpc_problem(lambda: stub.Repair(pb.RepairRequest(mesh=off, filename="b.off",
                                                            faces=[0])),
                       rpc.INVALID_ARGUMENT, "malformed-input")
    shapeless = pb.RepairRequest(mesh=mesh_file(mesh), region=pb.Region())
    assert_rpc_problem(lambda: stub.Repair(shapeless), rpc.INVALID_ARGUMENT, "malformed-input")
    assert_rpc_problem(lambda: stub.Repair(repair_pb(mesh, region, steps=0)),
                       rpc.INVALID_ARGUMENT, "invalid-option")
    assert_rpc_problem(lambda: stub.Repair(pb.RepairRequest(mesh=b"v 0 0 0\n" * 300_000,
                                                            faces=[0])),
                       rpc.RESOURCE_EXHAUSTED, "payload-too-large")


# ---------------------------------------------------------------------- metrics, docs
def test_repairs_are_measured(http, stub):
    mesh, region = CASES["faces"]
    assert post_repair(http, mesh, region, seed=SEED).status_code == 200
    assert post_repair(http, mesh, {"faces": []}).status_code == 422
    stub.Repair(repair_pb(mesh, region, seed=SEED))
    text = http.get("/metrics").text
    assert re.search(r'spacemesh_requests_total\{protocol="http",route="/repair",'
                     r'status="200"\} [1-9]', text)
    assert re.search(r'spacemesh_requests_total\{protocol="grpc",'
                     r'route="/spacemesh.v1.SpaceMesh/Repair",status="OK"\} [1-9]', text)
    for stage in ("decode_input", "queue", "cut", "patch", "encoder", "sampler",
                  "connectivity", "splice", "encode_output"):
        assert re.search(rf'spacemesh_repair_stage_seconds_count\{{stage="{stage}"\}} [1-9]',
                         text), stage
    assert re.search(r'spacemesh_repair_rejected_total\{kind="empty-region"\} [1-9]', text)
    assert re.search(r"spacemesh_repair_region_faces_count [1-9]", text)
    done = sum(float(v) for v in re.findall(r"spacemesh_repairs_total\{[^}]*\} (\S+)", text))
    assert done >= 2


def test_openapi_describes_repair(http):
    spec = http.get("/openapi.json").json()
    repair = spec["paths"]["/repair"]["post"]
    form = repair["requestBody"]["content"]["multipart/form-data"]
    assert set(form["schema"]["required"]) == {"file", "region"}
    assert set(form["examples"]) == {"faces", "vertices", "sphere", "box", "auto"}
    assert {p["name"] for p in repair["parameters"]} == {"format", "seed", "steps", "sampler",
                                                         "weld", "max_growth"}
    assert "weld" in form["schema"]["properties"]
    for status in ("200", "400", "413", "415", "422", "503"):
        assert status in repair["responses"], status
    kinds = {e["value"]["type"].rsplit("/", 1)[1]
             for e in repair["responses"]["422"]["content"][PROBLEM]["examples"].values()}
    assert {"invalid-region", "empty-region", "whole-mesh-region", "defects-outside-region",
            "region-too-large"} <= kinds
    assert "X-SpaceMesh-Repair" in repair["responses"]["200"]["headers"]
    assert "X-SpaceMesh-Welded-Vertices" in repair["responses"]["200"]["headers"]
    assert "501" not in repair["responses"]


# ---------------------------------------------------------------------- weld
#: A closed mesh stored flat-shaded (every triangle on vertices of its own), as GLB.
SMOOTH, BALL = CASES["sphere"]
FLAT = flat_shaded(SMOOTH)
FLAT_GLB = mesh_file(FLAT, "glb")
MERGED = FLAT.n_vertices - SMOOTH.n_vertices


def post_flat(http, region, **params):
    return post_repair(http, FLAT, region, filename="flat.glb", data=FLAT_GLB, seed=SEED,
                       **params)


def flat_pb(region: dict, **fields) -> pb.RepairRequest:
    fields.setdefault("steps", REPAIR_STEPS)
    return pb.RepairRequest(mesh=FLAT_GLB, filename="flat.glb", region=region_pb(region),
                            seed=SEED, format="obj", **fields)


def test_a_split_mesh_is_refused_with_a_hint_to_weld(http, stub):
    for params in ({}, {"weld": "false"}):  # never welded unless asked
        body = assert_problem(post_flat(http, BALL, **params), 422, "defects-outside-region")
        assert body["coincident_vertices"] == MERGED
        assert f"{MERGED} vertices share their exact position" in body["detail"]
        assert "weld=true" in body["detail"]
        assert "open-boundary" in {d["kind"] for d in body["defects"]}
    metadata = assert_rpc_problem(lambda: stub.Repair(flat_pb(BALL)),
                                  grpc.StatusCode.FAILED_PRECONDITION, "defects-outside-region")
    assert json.loads(metadata["problem-extensions"])["coincident_vertices"] == MERGED


def test_weld_repairs_a_split_glb_over_rest_and_grpc(http, stub):
    response = post_flat(http, BALL, weld="true")
    assert response.status_code == 200, response.text
    h = response.headers
    assert h["x-spacemesh-welded-vertices"] == str(MERGED)
    assert h["x-spacemesh-closed"] == h["x-spacemesh-manifold"] == h["x-spacemesh-oriented"] == (
        "true")
    repair = json.loads(h["x-spacemesh-repair"])
    assert repair["welded_vertices"] == MERGED
    out = load_mesh(response.content, file_type="obj")
    # the welded mesh repaired: faces outside the region keep their positions
    check_repair(SMOOTH, BALL, out.vertices, out.faces, repair)
    as_form = http.post("/repair", params={"format": "obj", "steps": REPAIR_STEPS},
                        files={"file": ("flat.glb", FLAT_GLB)},
                        data={"region": json.dumps(BALL), "seed": str(SEED), "weld": "on"})
    assert as_form.status_code == 200 and as_form.content == response.content
    reply = stub.Repair(flat_pb(BALL, weld=True))
    assert reply.mesh == response.content  # the same bytes over gRPC
    assert reply.repair.welded_vertices == MERGED and reply.stats.closed
    plain = stub.Repair(repair_pb(SMOOTH, BALL, seed=SEED))
    assert plain.repair.welded_vertices == 0


def test_weld_maps_vertex_regions_from_the_files_indices(http):
    position = int(SMOOTH.face_indices[-1])  # the last copy of this position in FLAT
    copy = len(FLAT.face_indices) - 1
    response = post_flat(http, {"vertices": [copy]}, weld="1")
    assert response.status_code == 200, response.text
    repair = json.loads(response.headers["x-spacemesh-repair"])
    around = sum(position in face for face in SMOOTH.face_indices.reshape(-1, 3).tolist())
    assert repair["requested_faces"] == around  # every face around it, not the one copy
    out = load_mesh(response.content, file_type="obj")
    check_repair(SMOOTH, {"vertices": [position]}, out.vertices, out.faces, repair)
    body = assert_problem(post_flat(http, {"vertices": [FLAT.n_vertices]}, weld="true"),
                          422, "invalid-region")
    assert f"the mesh has {FLAT.n_vertices} vertices" in body["detail"]  # the file's count


def test_invalid_weld_values_are_422(http):
    for where in ("query", "form"):
        if where == "query":
            response = post_flat(http, BALL, weld="maybe")
        else:
            response = http.post("/repair", files={"file": ("flat.glb", FLAT_GLB)},
                                 data={"region": json.dumps(BALL), "weld": "maybe"})
        body = assert_problem(response, 422, "invalid-option")
        assert body["option"] == "weld" and "weld" in body["detail"], where
