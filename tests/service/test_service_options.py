"""The generate options and the fit report over REST and gRPC, on a real server.

Every option a request sets must reach the generator unchanged: the server's answer
(mesh size, fit report, sample scores, resolved options) is compared with the tiny
model's own :meth:`MeshGenerator.generate` for the same options. ``start=points`` keeps
these fast (no denoiser with the default start time of 0).
"""

from __future__ import annotations

import grpc
import numpy as np
import pytest
from service_testing import BAD_OPTIONS

from spacemesh.geometry.surface import AUTO_OPEN_SHARE
from spacemesh.io import load_mesh
from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.options import GENERATE_ONLY, GenerateOptions
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from tests.validity import assert_valid_mesh

pytestmark = pytest.mark.slow

PROBLEM = "application/problem+json"
#: Option sets that must reach the generator (each with the test's seed).
GOOD_OPTIONS = [
    {"start": "points"},
    {"start": "points", "raw": True},
    {"start": "points", "target_vertices": 60},
    {"start": "points", "start_time": 0.5, "steps": 4},
    {"start": "points", "samples": 3},
    {"start": "points", "tolerance": 0.05},
    {"start": "noise", "sampler": "ddpm", "steps": 4},
    {"start": "points", "surface": "open"},
    {"start": "points", "surface": "closed"},
    {"start": "points", "face_type": "polygons"},
]


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server.grpc_target) as channel:
        yield pb_grpc.SpaceMeshStub(channel)


@pytest.fixture(scope="module")
def cloud(case):
    return case.points[::2]  # 150 points


def expected(generator, cloud, options: dict):
    """The generator's own result for ``options``, at the first seed that makes faces."""
    for seed in range(8):
        result = generator.generate(cloud, options=GenerateOptions(seed=seed, **options))
        if result.mesh.n_faces:
            return seed, result
    pytest.fail(f"the tiny model made no surface with {options} for 8 seeds")  # never a skip


def fit_headers(fit: dict) -> dict[str, str]:
    return {"x-spacemesh-fit-" + k.replace("_", "-"): str(v).lower() if isinstance(v, bool)
            else str(v) for k, v in fit.items()}


# ---------------------------------------------------------------------- 422s
@pytest.mark.parametrize(("options", "name"), BAD_OPTIONS)
@pytest.mark.parametrize("where", ["query", "json", "form"])
def test_bad_options_are_422_over_rest(http, cloud, options, name, where):
    if where == "query":
        response = http.post("/generate", params=options, json={"points": cloud.tolist()})
    elif where == "json":
        response = http.post("/generate", json={"points": cloud.tolist(), **options})
    else:
        text = "\n".join(" ".join(map(repr, p)) for p in cloud.tolist()).encode()
        response = http.post("/generate", files={"file": ("c.xyz", text)},
                             data={k: str(v) for k, v in options.items()})
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith(PROBLEM)
    body = response.json()
    assert body["type"] == "https://spacemesh.dev/problems/invalid-option"
    assert body["option"] == name and name in body["detail"]


@pytest.mark.parametrize(("options", "name"), [b for b in BAD_OPTIONS if "raw" not in b[0]])
def test_bad_options_are_invalid_argument_over_grpc(stub, cloud, options, name):
    request = pb.GenerateRequest(points=pb.Points(xyz=cloud.ravel().tolist()), **options)
    for call in (stub.Generate, lambda r: list(stub.GenerateStream(r))):
        with pytest.raises(grpc.RpcError) as info:
            call(request)
        assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        metadata = dict(info.value.trailing_metadata())
        assert metadata["problem-type"] == "https://spacemesh.dev/problems/invalid-option"
        assert metadata["problem-status"] == "422"
        assert f'"option":"{name}"' in metadata["problem-extensions"]
        assert name in info.value.details()


def test_generate_only_options_are_not_options_of_repair(http):
    from spacemesh.examples import icosphere
    from spacemesh.io import export_mesh

    files = {"file": ("m.obj", export_mesh(icosphere(1), "obj"))}
    region = {"region": '{"faces": [0, 1, 2]}'}
    response = http.post("/repair", params={"steps": 4, "seed": 1, "start": "bogus",
                                            "samples": 0, "raw": "maybe"},
                         files=files, data=region)
    assert response.status_code == 422, response.text  # refused, as any unknown option
    body = response.json()
    assert body["type"] == "https://spacemesh.dev/problems/invalid-option"
    assert body["option"] == "raw" and body["unknown"] == ["raw", "samples", "start"]
    response = http.post("/repair", params={"steps": 4, "seed": 1}, files=files, data=region)
    assert response.status_code == 200, response.text
    for name in GENERATE_ONLY:
        assert name not in pb.RepairRequest.DESCRIPTOR.fields_by_name
        assert f"x-spacemesh-{name.replace('_', '-')}" not in response.headers
    assert "x-spacemesh-fit-coverage" not in response.headers  # no points: no fit report


# ---------------------------------------------------------------------- options reach the model
@pytest.mark.parametrize("options", GOOD_OPTIONS, ids=lambda o: ",".join(o))
def test_rest_options_reach_the_generator(http, generator, cloud, options):
    seed, result = expected(generator, cloud, options)
    response = http.post("/generate", json={"points": cloud.tolist(), "seed": seed,
                                            "format": "json", **options})
    assert response.status_code == 200, response.text
    h, body = response.headers, response.json()
    resolved = result.options
    assert h["x-spacemesh-seed"] == str(resolved.seed) == str(body["seed"])
    for name in ("steps", "sampler", "start", "start_time", "samples", "surface",
                 "face_type"):
        header = f"x-spacemesh-{name.replace('_', '-')}"
        if getattr(resolved, name) is None:  # start_time with start=noise
            assert header not in h and body[name] is None
            continue
        assert h[header] == str(getattr(resolved, name))
        assert body[name] == getattr(resolved, name)
    assert h["x-spacemesh-raw"] == str(resolved.raw).lower() and body["raw"] is resolved.raw
    for name in ("target_vertices", "tolerance"):
        header = f"x-spacemesh-{name.replace('_', '-')}"
        if getattr(resolved, name) is None:
            assert header not in h and body[name] is None
        else:
            assert h[header] == str(getattr(resolved, name)) and body[name] == getattr(
                resolved, name)
    assert (resolved.tolerance is None) == ("tolerance_met" not in result.fit.to_dict())
    assert len(body["vertices"]) == result.mesh.n_vertices
    assert len(body["faces"]) == result.mesh.n_faces
    fit = result.fit.to_dict()
    assert {k: v for k, v in h.items() if k.startswith("x-spacemesh-fit-")} == fit_headers(fit)
    assert body["stats"]["fit"] == fit
    scores = result.sample_scores
    assert [(s["seed"], s["score"]) for s in body["sample_scores"]] == scores
    assert h["x-spacemesh-sample-scores"] == ",".join(f"{s}:{x!r}" for s, x in scores)


@pytest.mark.parametrize("options", GOOD_OPTIONS, ids=lambda o: ",".join(o))
def test_grpc_options_reach_the_generator(stub, generator, cloud, options):
    seed, result = expected(generator, cloud, options)
    request = pb.GenerateRequest(points=pb.Points(xyz=cloud.ravel().tolist()), seed=seed,
                                 format="obj", **options)
    reply = stub.Generate(request)
    resolved = result.options
    for name in ("seed", "steps", "sampler", "start", "start_time", "samples", "raw",
                 "surface", "face_type"):
        if getattr(resolved, name) is None:  # start_time with start=noise: unset
            assert not reply.HasField(name), name
            continue
        assert getattr(reply, name) == getattr(resolved, name), name
    assert reply.HasField("target_vertices") == (resolved.target_vertices is not None)
    assert reply.HasField("tolerance") == (resolved.tolerance is not None)
    if resolved.tolerance is not None:
        assert reply.tolerance == resolved.tolerance
    assert reply.stats.vertices == result.mesh.n_vertices
    fit = {f.name: getattr(reply.stats.fit, f.name) for f in pb.FitReport.DESCRIPTOR.fields
           if not f.has_presence or reply.stats.fit.HasField(f.name)}
    assert fit == result.fit.to_dict()
    assert [(s.seed, s.score) for s in reply.sample_scores] == result.sample_scores
    assert load_mesh(reply.mesh, file_type="obj").n_faces == result.mesh.n_faces


def test_samples_return_the_best_fit_and_its_seed_reproduces_it(http, cloud):
    def post(**options):
        response = http.post("/generate", params={"format": "obj", "start": "points",
                                                  **options}, json={"points": cloud.tolist()})
        assert response.status_code == 200, response.text
        return response

    best = post(seed=5, samples=4)
    scores = [item.split(":") for item in best.headers["x-spacemesh-sample-scores"].split(",")]
    assert [int(s) for s, _ in scores] == [5, 6, 7, 8]
    winner = min(scores, key=lambda item: (float(item[1]), int(item[0])))[0]
    assert best.headers["x-spacemesh-seed"] == winner
    assert best.headers["x-spacemesh-samples"] == "4"
    again = post(seed=int(winner), samples=1)
    assert again.content == best.content
    assert again.headers["x-spacemesh-fit-points-to-mesh-mean"] == (
        best.headers["x-spacemesh-fit-points-to-mesh-mean"])


def test_every_generated_mesh_reports_its_fit(http, stub, case):
    response = http.post("/generate", json={"points": case.points.tolist(),
                                            "seed": case.good_seed, "format": "json"})
    assert response.status_code == 200
    fit = response.json()["stats"]["fit"]
    assert 0.0 <= fit["coverage"] <= 1.0 and fit["components"] >= 1
    assert fit["n_points"] == len(case.points)
    assert np.isclose(fit["points_to_mesh_mean_rel"] * fit["diagonal"],
                      fit["points_to_mesh_mean"])
    assert response.headers["x-spacemesh-fit-n-points"] == str(len(case.points))
    reply = stub.Generate(pb.GenerateRequest(points=pb.Points(xyz=case.points.ravel().tolist()),
                                             seed=case.good_seed))
    assert reply.stats.HasField("fit") and reply.stats.fit.n_points == len(case.points)
    assert reply.stats.fit.coverage == fit["coverage"]
    # the topology a user sees: the same numbers as the mesh's own check, on every transport
    assert fit["pieces"] >= 1 and fit["boundary_loops"] == 0
    assert fit["genus"] == response.json()["stats"]["genus"]
    assert response.headers["x-spacemesh-fit-pieces"] == str(fit["pieces"])
    assert response.headers["x-spacemesh-fit-genus"] == str(fit["genus"])
    assert (reply.stats.fit.pieces, reply.stats.fit.genus, reply.stats.fit.boundary_loops) == (
        fit["pieces"], fit["genus"], fit["boundary_loops"])
    # and the points' own piece count, which the mesh's pieces agree with or not
    assert fit["points_pieces"] >= 1
    assert response.headers["x-spacemesh-fit-points-pieces"] == str(fit["points_pieces"])
    assert reply.stats.fit.HasField("points_pieces")
    assert reply.stats.fit.points_pieces == fit["points_pieces"]
    # and what the points are like: outliers set aside, the noise of the rest
    assert 0.0 <= fit["points_outliers"] < 0.05 and 0.0 <= fit["points_noise"] < 0.05
    assert response.headers["x-spacemesh-fit-points-noise"] == str(fit["points_noise"])
    assert response.headers["x-spacemesh-fit-points-outliers"] == str(fit["points_outliers"])
    assert reply.stats.fit.HasField("points_noise") and reply.stats.fit.HasField(
        "points_outliers")
    assert (reply.stats.fit.points_noise, reply.stats.fit.points_outliers) == (
        fit["points_noise"], fit["points_outliers"])


# ---------------------------------------------------------------------- surface=open
@pytest.fixture(scope="module")
def one_sided(case):
    """The test cloud seen from +z only (its upper half)."""
    return case.points[case.points[:, 2] > np.median(case.points[:, 2])]


@pytest.mark.parametrize("fmt", ["glb", "obj", "ply", "off", "json"])
def test_an_open_surface_is_valid_with_its_rims_in_every_format(http, generator, one_sided,
                                                                 fmt):
    seed, result = expected(generator, one_sided, {"start": "points", "surface": "open"})
    assert result.fit.open_surface is True
    response = http.post("/generate", json={"points": one_sided.tolist(), "seed": seed,
                                            "start": "points", "surface": "open",
                                            "format": fmt})
    assert response.status_code == 200, response.text
    h = response.headers
    assert h["x-spacemesh-surface"] == "open" and h["x-spacemesh-fit-open-surface"] == "true"
    assert h["x-spacemesh-closed"] == str(result.fit.boundary_loops == 0).lower()
    if fmt == "json":
        body = response.json()
        mesh = PolygonMesh.from_faces(np.asarray(body["vertices"]),
                                      [np.asarray(f) for f in body["faces"]])
    else:
        mesh = load_mesh(response.content, file_type=fmt)
    assert_valid_mesh(mesh, open_surface=True)
    assert int(h["x-spacemesh-fit-boundary-loops"]) == result.fit.boundary_loops


def test_auto_tells_why_it_decided_over_rest_and_grpc(http, stub, case, one_sided):
    for points, opened in ((case.points, False), (one_sided, True)):
        response = http.post("/generate", json={"points": points.tolist(), "seed": 0,
                                                "start": "points", "format": "json"})
        assert response.status_code == 200, response.text
        body = response.json()
        fit = body["stats"]["fit"]
        assert body["surface"] == "auto"
        assert fit["open_surface"] is opened
        assert (fit["unsupported_area"] >= AUTO_OPEN_SHARE) is opened
        assert body["stats"]["closed"] is (not opened or fit["boundary_loops"] == 0)
        reply = stub.Generate(pb.GenerateRequest(points=pb.Points(xyz=points.ravel().tolist()),
                                                 seed=0, start="points", format="obj"))
        assert reply.surface == "auto"
        assert reply.stats.fit.open_surface is opened
        assert reply.stats.fit.unsupported_area == fit["unsupported_area"]
