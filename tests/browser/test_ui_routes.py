"""The page's routes on a real server, without a browser: the page and its vendored
assets, its config (from the service's option tables), ``/ui/preview``, ``--no-ui``, and
API keys (page open, work behind the key)."""

from __future__ import annotations

import httpx
import numpy as np
import pytest
from service_testing import as_ply, mesh_file

from spacemesh.examples import icosphere
from spacemesh_service.inputs import INPUT_FORMATS, MESH_FORMATS
from spacemesh_service.options import GENERATE_ROUTE_OPTIONS, REPAIR_ROUTE_OPTIONS
from spacemesh_service.outputs import OUTPUT_FORMATS
from spacemesh_service.ui import PREVIEW_POINTS, preview

pytestmark = pytest.mark.slow

PROBLEM = "application/problem+json"
KEY = "page-test-key-0123456789"


@pytest.fixture(scope="module")
def http(server):
    with httpx.Client(base_url=server.url, timeout=60) as client:
        yield client


def test_the_page_and_its_assets_are_served(http):
    page = http.get("/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert '"three": "/static/vendor/three/three.module.min.js"' in page.text
    assert "//cdn" not in page.text and "https://" not in page.text  # nothing from outside
    for asset in ("app.js", "app.css", "vendor/three/three.module.min.js",
                  "vendor/three/three.core.min.js", "vendor/three/OrbitControls.js",
                  "vendor/three/LICENSE"):
        response = http.get(f"/static/{asset}")
        assert response.status_code == 200 and response.content, asset
    assert "MIT License" in http.get("/static/vendor/three/LICENSE").text
    assert http.get("/static/nothing.js").status_code == 404
    assert "/" not in http.get("/openapi.json").json()["paths"]


def test_the_config_comes_from_the_option_tables(http):
    config = http.get("/static/config.json").json()
    assert [p["name"] for p in config["generate_options"]] == [
        o.name for o in GENERATE_ROUTE_OPTIONS]
    assert [p["name"] for p in config["repair_options"]] == [o.name for o in REPAIR_ROUTE_OPTIONS]
    assert config["generate_options"] == [o.parameter() for o in GENERATE_ROUTE_OPTIONS]
    assert config["output_formats"] == list(OUTPUT_FORMATS)
    assert config["input_formats"] == {"points": list(INPUT_FORMATS), "mesh": list(MESH_FORMATS)}
    paths = http.get("/openapi.json").json()["paths"]
    for route in ("generate", "generate_stream", "repair", "repair_stream", "preview"):
        assert config["routes"][route] in paths, route


def test_preview_reads_points_and_meshes_as_the_routes_do(http, case):
    points = http.post("/ui/preview", files={"file": ("cloud.ply", as_ply(case.points))},
                       data={"kind": "points"})
    assert points.status_code == 200, points.text
    body = points.json()
    assert body["count"] == len(case.points) <= PREVIEW_POINTS
    np.testing.assert_allclose(np.reshape(body["points"], (-1, 3)), case.points, rtol=1e-6)
    big = np.random.default_rng(0).standard_normal((PREVIEW_POINTS + 5, 3))
    too_many = http.post("/ui/preview", files={"file": ("big.npy", _npy(big))})
    assert too_many.status_code == 413  # the limits of /generate (max_points 5000 here)
    many = preview(_npy(big), "big.npy", "points", None)  # a server without that limit
    assert many["count"] == len(big) and len(many["points"]) // 3 <= PREVIEW_POINTS
    np.testing.assert_array_equal(np.reshape(many["points"], (-1, 3))[:2], big[[0, 2]])

    sphere = icosphere(1)
    mesh = http.post("/ui/preview", files={"file": ("sphere.off", mesh_file(sphere, "off"))},
                     data={"kind": "mesh"}).json()
    assert mesh["faces"] == [list(map(int, f)) for f in sphere.faces]
    np.testing.assert_allclose(np.reshape(mesh["vertices"], (-1, 3)), sphere.vertices)


def _npy(array: np.ndarray) -> bytes:
    import io

    out = io.BytesIO()
    np.save(out, array)
    return out.getvalue()


def test_preview_errors_are_problems(http):
    cases = [
        (dict(files={"file": ("x.ply", b"ply\nnot a ply\n")}), 400),
        (dict(files={"file": ("x.ply", b"1 2 3\n")}, data={"kind": "pictures"}), 400),
        (dict(data={"kind": "points"}, files={"other": ("x.xyz", b"1 2 3\n")}), 400),
        (dict(files={"file": ("x.doc", b"hello")}, data={"kind": "mesh"}), 415),
    ]
    for kwargs, status in cases:
        response = http.post("/ui/preview", **kwargs)
        assert response.status_code == status, response.text
        assert response.headers["content-type"].startswith(PROBLEM)
        assert response.json()["detail"]


def test_no_ui_leaves_the_page_out(start_server, generator):
    server = start_server(generator, ui=False)
    with httpx.Client(base_url=server.url, timeout=30) as client:
        for path in ("/", "/static/config.json", "/static/app.js"):
            response = client.get(path)
            assert response.status_code == 404, path
            assert response.headers["content-type"].startswith(PROBLEM)
        assert client.post("/ui/preview", files={"file": ("a.xyz", b"1 2 3\n")}
                           ).status_code == 404
        assert client.get("/v2/health/ready").status_code == 200


def test_with_api_keys_the_page_is_open_and_the_work_needs_the_key(start_server, generator,
                                                                   case, tmp_path):
    keys = tmp_path / "keys.txt"
    keys.write_text(KEY + "\n")
    server = start_server(generator, api_keys=keys)
    files = {"file": ("cloud.ply", as_ply(case.points))}
    with httpx.Client(base_url=server.url, timeout=60) as client:
        for path in ("/", "/static/app.js", "/static/config.json"):
            assert client.get(path).status_code == 200, path
        for route in ("/ui/preview", "/generate/stream"):
            response = client.post(route, files=files)
            assert response.status_code == 401, route
            assert response.headers["content-type"].startswith(PROBLEM)
        auth = {"Authorization": f"Bearer {KEY}"}
        assert client.post("/ui/preview", files=files, headers=auth).status_code == 200
        streamed = client.post("/generate/stream", files=files, headers=auth,
                               params={"seed": case.good_seed})
        assert streamed.status_code == 200 and "event: result" in streamed.text
