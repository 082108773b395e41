"""The REST API on a real server (uvicorn on loopback, tiny exported model)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from service_testing import UPLOADS

from spacemesh.io import load_mesh
from spacemesh.topology import check_topology

pytestmark = pytest.mark.slow

PROBLEM = "application/problem+json"


def assert_problem(response, status: int, slug: str) -> dict:
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith(PROBLEM)
    body = response.json()
    assert body["type"] == f"https://spacemesh.dev/problems/{slug}", body
    assert body["status"] == status and body["title"] and body["detail"]
    return body


def generate_json(http, points, **options):
    return http.post("/generate", json={"points": np.asarray(points).tolist(), **options})


# ---------------------------------------------------------------------- health, metadata
def test_health_and_server_metadata(http):
    assert http.get("/v2/health/live").json() == {"live": True}
    ready = http.get("/v2/health/ready")
    assert ready.status_code == 200 and ready.json() == {"ready": True}
    assert http.get("/v2").json()["name"] == "spacemesh"


def test_model_metadata(http, generator):
    name = generator.repository.name
    meta = http.get(f"/v2/models/{name}").json()
    assert meta["name"] == name and meta["versions"] == ["1"] and meta["ready"] is True
    assert meta["limits"]["max_points"] == 5000 and meta["limits"]["min_points"] == 16
    assert meta["limits"]["max_upload_bytes"] == 2_000_000
    assert meta["limits"]["max_vertices"] == generator.spec.max_vertices
    assert meta["sampler"] == {"sampler": generator.spec.method, "default_steps": 8,
                               "timesteps": 64, "start": generator.spec.start,
                               "start_time": generator.spec.start_time}
    assert {"ply", "xyz", "pts", "txt", "npy", "npz", "obj"} <= set(meta["input_formats"]["upload"])
    assert set(meta["output_formats"]) == {"glb", "gltf", "obj", "ply", "off", "json"}
    assert meta["data"]["source"] == "toy"  # the training data card from the manifest
    assert "validation" in meta["metrics"]
    assert all(len(f["sha256"]) == 64 for f in meta["files"].values())
    assert http.get(f"/v2/models/{name}/versions/1").json() == meta
    assert http.get(f"/v2/models/{name}/ready").json() == {"name": name, "ready": True}
    assert_problem(http.get(f"/v2/models/{name}/versions/7"), 404, "model-not-found")
    assert_problem(http.get("/v2/models/nope"), 404, "model-not-found")


# ---------------------------------------------------------------------- output formats
@pytest.mark.parametrize("fmt", ["glb", "gltf", "obj", "ply", "off", "json"])
def test_every_output_format(http, case, fmt):
    response = generate_json(http, case.points, seed=case.good_seed, format=fmt)
    assert response.status_code == 200, response.text
    media = {"glb": "model/gltf-binary", "gltf": "model/gltf+json", "obj": "model/obj",
             "ply": "model/x-ply", "off": "model/x-off", "json": "application/json"}[fmt]
    assert response.headers["content-type"] == media
    h = response.headers
    assert h["x-spacemesh-seed"] == str(case.good_seed)
    assert h["x-spacemesh-manifold"] == h["x-spacemesh-closed"] == h["x-spacemesh-oriented"] == (
        "true")
    assert re.fullmatch(r"\d+:\d+(,\d+:\d+)*", h["x-spacemesh-face-degrees"])
    assert "server-timing" in h and "x-spacemesh-steps" in h and "x-spacemesh-model" in h
    n_vertices, n_faces = int(h["x-spacemesh-vertices"]), int(h["x-spacemesh-faces"])
    degrees = {int(k): int(v) for k, v in
               (p.split(":") for p in h["x-spacemesh-face-degrees"].split(","))}
    assert sum(degrees.values()) == n_faces
    if fmt == "json":
        body = response.json()
        assert len(body["vertices"]) == n_vertices and len(body["faces"]) == n_faces
        assert body["seed"] == case.good_seed and body["stats"]["closed"] is True
        vertices = np.asarray(body["vertices"])
    else:
        mesh = load_mesh(response.content, file_type=fmt)
        vertices = mesh.vertices
        if fmt in ("obj", "ply", "off"):  # polygons kept
            assert mesh.n_faces == n_faces and mesh.degree_histogram() == degrees
            assert check_topology(mesh).is_closed_oriented_manifold
        else:  # triangulated
            assert mesh.is_triangle_mesh()
            assert mesh.n_faces == sum((k - 2) * v for k, v in degrees.items())
    # the mesh is in the input's frame and scale
    lo, hi = case.points.min(axis=0), case.points.max(axis=0)
    margin = (hi - lo).max()
    assert np.all(vertices >= lo - margin) and np.all(vertices <= hi + margin)


# ---------------------------------------------------------------------- upload formats
def test_every_upload_format_gives_the_same_mesh(http, case):
    reference = generate_json(http, case.points, seed=case.good_seed, format="obj")
    assert reference.status_code == 200
    for name, (filename, encode) in UPLOADS.items():
        response = http.post("/generate", params={"seed": case.good_seed, "format": "obj"},
                             files={"file": (filename, encode(case.points))})
        assert response.status_code == 200, (name, response.text)
        assert response.content == reference.content, name


def test_options_as_query_or_form_fields(http, case):
    file = {"file": ("cloud.xyz", UPLOADS["xyz"][1](case.points))}
    by_query = http.post("/generate", params={"seed": case.good_seed, "format": "off"},
                         files=file)
    by_form = http.post("/generate", data={"seed": str(case.good_seed), "format": "off"},
                        files=file)
    form_wins = http.post("/generate", params={"seed": 999, "format": "glb"},
                          data={"seed": str(case.good_seed), "format": "off"}, files=file)
    assert by_query.status_code == 200
    assert by_query.content == by_form.content == form_wins.content
    assert form_wins.headers["content-type"] == "model/x-off"


def test_normals_are_accepted(http, case):
    normals = case.points - case.points.mean(axis=0)
    response = generate_json(http, case.points, normals=normals.tolist(), seed=case.good_seed)
    assert response.status_code == 200


def test_the_seed_used_is_reported_and_replays(http, case):
    first = generate_json(http, case.points, format="obj")
    if first.status_code == 200:
        seed = int(first.headers["x-spacemesh-seed"])
    else:
        seed = assert_problem(first, 422, "no-surface")["seed"]
    again = generate_json(http, case.points, format="obj", seed=seed)
    assert again.status_code == first.status_code
    if first.status_code == 200:
        assert again.content == first.content
    else:  # the problem reports wall-clock timings, which differ run to run
        assert {**again.json(), "timings": None} == {**first.json(), "timings": None}


# ---------------------------------------------------------------------- errors
def test_malformed_input_is_400(http):
    ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n"
    assert_problem(http.post("/generate", files={"file": ("c.ply", ply)}), 400,
                   "malformed-input")
    assert_problem(http.post("/generate", content=b"{not json",
                             headers={"content-type": "application/json"}),
                   400, "malformed-input")
    assert_problem(http.post("/generate", json={"points": [[0, 0]]}), 400, "malformed-input")
    assert_problem(http.post("/generate", data={"seed": "1"}, files={"other": ("a", b"1")}),
                   400, "malformed-input")
    # a RecursionError (20 000 levels: fewer values than this server's JSON value limit)
    deep = b'{"points": ' + b"[" * 20_000 + b"]" * 20_000 + b"}"
    body = assert_problem(http.post("/generate", content=deep,
                                    headers={"content-type": "application/json"}),
                          400, "malformed-input")
    assert "nested too deeply" in body["detail"]


def test_invalid_format_and_invalid_options_are_422(http, case):
    points = case.points.tolist()
    response = http.post("/generate", params={"format": "stl"}, json={"points": points})
    assert assert_problem(response, 422, "invalid-option")["option"] == "format"
    for params in ({"steps": 0}, {"steps": 100000}, {"seed": -3}, {"seed": "abc"},
                   {"sampler": "euler"}):
        response = http.post("/generate", params=params, json={"points": points})
        assert assert_problem(response, 422, "invalid-option")["option"] == next(iter(params))


def test_too_large_is_413(http, case):
    many = np.random.default_rng(1).standard_normal((5001, 3))
    body = assert_problem(generate_json(http, many), 413, "too-many-points")
    assert body["limit"] == 5000
    xyz = UPLOADS["xyz"][1](many)
    assert_problem(http.post("/generate", files={"file": ("c.xyz", xyz)}), 413,
                   "too-many-points")
    big = b"0 0 0\n" * 400_000  # 2.4 MB > 2 MB
    assert_problem(http.post("/generate", files={"file": ("c.xyz", big)}), 413,
                   "payload-too-large")

    def chunks():  # no Content-Length: the limit is enforced while reading
        for _ in range(30):
            yield b"[" * 100_000

    assert_problem(http.post("/generate", content=chunks(),
                             headers={"content-type": "application/json"}),
                   413, "payload-too-large")


def test_unsupported_format_is_415(http):
    junk = bytes(range(256)) * 10
    assert_problem(http.post("/generate", files={"file": ("c.docx", junk)}), 415,
                   "unsupported-format")
    assert_problem(http.post("/generate", files={"file": ("upload", junk)}), 415,
                   "unsupported-format")
    assert_problem(http.post("/generate", content=b"1 2 3",
                             headers={"content-type": "text/plain"}), 415,
                   "unsupported-format")


def test_unusable_geometry_is_422(http, case):
    assert_problem(generate_json(http, case.points[:10]), 422, "too-few-points")
    nan = case.points.copy()
    nan[5, 2] = np.nan
    body = json.dumps({"points": nan.tolist()})  # the NaN literal
    assert_problem(http.post("/generate", content=body,
                             headers={"content-type": "application/json"}),
                   422, "non-finite")
    xyz = UPLOADS["xyz"][1](case.points).replace(b"\n", b"\ninf 0 0\n", 1)
    assert_problem(http.post("/generate", files={"file": ("c.xyz", xyz)}), 422, "non-finite")
    rng = np.random.default_rng(2)
    t = rng.standard_normal((40, 1))
    flat = np.hstack([rng.standard_normal((40, 2)), np.full((40, 1), 3.0)])
    for points, word in ((np.ones((40, 3)), "identical"),
                         (np.hstack([t, t, t]), "collinear"), (flat, "coplanar")):
        body = assert_problem(generate_json(http, points), 422, "degenerate-geometry")
        assert word in body["detail"]
    assert_problem(generate_json(http, case.points, normals=case.points[:5].tolist()), 422,
                   "invalid-normals")


def test_no_surface_is_422(http, case):
    body = assert_problem(generate_json(http, case.points, **case.no_surface), 422,
                          "no-surface")
    assert body["seed"] == case.no_surface["seed"]


def test_other_errors_are_problems_too(http):
    assert_problem(http.get("/nowhere"), 404, "not-found")
    for route in ("/generate", "/repair"):
        response = http.get(route)
        assert_problem(response, 405, "method-not-allowed")
        assert response.headers["allow"] == "POST"
    assert http.post("/metrics").headers["allow"] == "GET"
    assert_problem(http.post("/repair"), 415, "unsupported-format")  # no multipart body


# ---------------------------------------------------------------------- metrics, docs
def test_metrics(http, case):
    assert generate_json(http, case.points, seed=case.good_seed).status_code == 200
    text = http.get("/metrics").text
    assert re.search(r'spacemesh_requests_total\{protocol="http",route="/generate",'
                     r'status="200"\} [1-9]', text)
    assert re.search(r'spacemesh_requests_total\{.*route="/generate",status="422"\}', text)
    for stage in ("decode_input", "queue", "encoder", "sampler", "connectivity",
                  "extraction", "encode_output"):
        assert re.search(rf'spacemesh_stage_seconds_count\{{stage="{stage}"\}} [1-9]', text), stage
    assert re.search(r'spacemesh_request_seconds_bucket\{le="[^"]+",protocol="http",'
                     r'route="/generate"\}', text)
    for name in ("spacemesh_queue_depth", "spacemesh_batch_size_count",
                 "spacemesh_inflight_requests", "spacemesh_ready 1.0"):
        assert name in text


def test_openapi(http):
    spec = http.get("/openapi.json").json()
    paths = spec["paths"]
    for path in ("/generate", "/repair", "/v2/health/live", "/v2/health/ready",
                 "/v2/models/{name}", "/v2/models/{name}/versions/{version}", "/metrics"):
        assert path in paths, path
    generate = paths["/generate"]["post"]
    body = generate["requestBody"]["content"]
    assert "file" in body["multipart/form-data"]["schema"]["properties"]
    assert body["application/json"]["examples"]
    assert [p["name"] for p in generate["parameters"]] == [
        "format", "seed", "steps", "sampler", "start", "start_time", "target_vertices",
        "tolerance", "samples", "raw", "surface", "face_type"]
    schemas = {p["name"]: p["schema"] for p in generate["parameters"]}
    assert schemas["surface"]["enum"] == ["auto", "closed", "open"]
    assert schemas["tolerance"] == {**schemas["tolerance"], "type": "number",
                                    "minimum": 1e-4, "maximum": 0.5}
    assert schemas["samples"] == {**schemas["samples"], "type": "integer", "minimum": 1,
                                  "maximum": 16}
    assert schemas["start"]["enum"] == ["noise", "points"]
    assert schemas["raw"]["type"] == "boolean" and schemas["start_time"]["type"] == "number"
    form = body["multipart/form-data"]["schema"]["properties"]
    json_fields = spec["components"]["schemas"]["PointsRequest"]["properties"]
    assert set(schemas) <= set(form) and set(schemas) <= set(json_fields)
    for status in ("200", "400", "413", "415", "422", "503", "504"):
        assert status in generate["responses"], status
    assert generate["responses"]["422"]["content"][PROBLEM]["examples"]
    headers = generate["responses"]["200"]["headers"]
    for name in ("Seed", "Start", "Start-Time", "Raw", "Sample-Scores", "Fit-Coverage",
                 "Fit-Points-To-Mesh-Mean", "Fit-Self-Intersections"):
        assert "X-SpaceMesh-" + name in headers, name
    for schema in ("PointsRequest", "MeshJSON", "ProblemModel"):
        assert schema in spec["components"]["schemas"]
    assert http.get("/docs").status_code == 200
