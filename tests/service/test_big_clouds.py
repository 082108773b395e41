"""Clouds of more points than the pipeline works on, on a real server with the default
limits: binary clouds are reduced (and say so), text clouds and oversize binary clouds are
refused with 413, and ``spacemesh generate`` reduces them too."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from service_testing import as_las, as_npy, as_npz, as_ply, as_text, make_cloud

from spacemesh.io.reduce import reduce_cloud
from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology

pytestmark = pytest.mark.slow

#: Above the text limit and the working size (both 200,000 by default).
BIG = 300_000


@pytest.fixture(scope="module")
def big_case(generator):
    """A 300,000-point cloud (float32-exact) and a seed whose mesh has faces."""
    from spacemesh_service.settings import Settings

    points = make_cloud(BIG, seed=7)
    working, _ = reduce_cloud(points, None, Settings.model_fields["working_points"].default)
    # a seed with faces both raw (the tests of the reduction, which need no fit) and
    # through the geometry stage (the command line's test)
    seed = next((s for s in range(6) if generator.generate(working, seed=s, raw=True).mesh.n_faces
                 and generator.generate(working, seed=s).mesh.n_faces), None)
    if seed is None:
        pytest.fail("the tiny model made no surface from the reduced 300k cloud", pytrace=False)
    return points, seed


@pytest.fixture(scope="module")
def default_server(start_server, generator):
    """A server with the default point and byte limits."""
    from spacemesh_service.settings import Settings

    defaults = {name: Settings.model_fields[name].default for name in
                ("max_points", "max_text_points", "working_points", "max_upload_bytes",
                 "max_text_bytes")}
    return start_server(generator, **defaults)


@pytest.fixture(scope="module")
def default_http(default_server):
    import httpx

    with httpx.Client(base_url=default_server.url, timeout=120) as client:
        yield client


def test_the_sdk_says_the_points_were_reduced_over_rest_and_grpc(default_server, big_case,
                                                                   tmp_path):
    pytest.importorskip("spacemesh_client")
    from spacemesh_client import Client

    points, seed = big_case
    cloud = tmp_path / "big.npy"
    np.save(cloud, points.astype(np.float32))
    meshes = []
    for url in (default_server.url, "grpc://" + default_server.grpc_target):
        with Client(url, timeout=120) as client:
            meshes.append(client.generate(cloud, seed=seed, format="obj", raw=True))
    for mesh in meshes:
        assert mesh.points_reduced == {"read": BIG, "used": 200_000}
    assert meshes[0].data == meshes[1].data
    with Client(default_server.url) as client:  # a small cloud is not reduced
        assert client.generate(points[:5000], seed=seed, format="obj",
                               raw=True).points_reduced is None
    # and the SDK's command line says so too
    cli = [sys.executable, "-c", "from spacemesh_client.cli import main; main()", "generate",
           str(cloud), "-o", str(tmp_path / "m.obj"), "--url", default_server.url, "--seed",
           str(seed), "--raw"]
    done = subprocess.run([*cli, "--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["points_reduced"] == {"read": BIG, "used": 200_000}
    done = subprocess.run(cli, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "the server used 200,000 of the 300,000 points read" in (
        done.stderr)


def test_binary_clouds_above_the_text_limit_are_reduced(default_http, big_case):
    points, seed = big_case
    bodies = {}
    for name, encode in [("c.ply", as_ply), ("c.npy", as_npy), ("c.npz", as_npz),
                         ("c.las", as_las), ("c.laz", lambda p: as_las(p, compressed=True))]:
        response = default_http.post("/generate", params={"seed": seed, "format": "json",
                                                           "raw": True},
                                     files={"file": (name, encode(points))})
        assert response.status_code == 200, (name, response.text)
        assert response.headers["x-spacemesh-points-read"] == str(BIG)
        assert response.headers["x-spacemesh-points-used"] == "200000"
        body = response.json()
        assert body["points_reduced"] == {"read": BIG, "used": 200_000}
        mesh = PolygonMesh.from_faces(body["vertices"], body["faces"])
        assert mesh.n_faces and check_topology(mesh).is_closed_oriented_manifold
        bodies[name] = response.content
    assert len(set(bodies.values())) == 1  # the same points whatever the binary format


def test_text_clouds_above_the_text_limit_are_413(default_http):
    text = as_text(make_cloud(200_001, seed=1))
    response = default_http.post("/generate", files={"file": ("c.xyz", text)})
    assert response.status_code == 413 and response.headers["content-type"].startswith(
        "application/problem+json")
    body = response.json()
    assert body["type"].endswith("/too-many-points") and body["limit"] == 200_000
    assert "200000" in body["detail"]


def test_binary_clouds_above_the_point_limit_are_413(default_http):
    from spacemesh_service.settings import Settings

    limit = Settings.model_fields["max_points"].default
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {limit + 1}\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n").encode()
    response = default_http.post("/generate", files={"file": ("c.ply", header + b"\0" * 64)})
    assert response.status_code == 413, response.text
    body = response.json()
    assert body["type"].endswith("/too-many-points") and body["limit"] == limit


def test_the_cli_reduces_a_big_npy(toy_repository, big_case, tmp_path):
    from typer.testing import CliRunner

    from spacemesh.cli import _register, app

    points, seed = big_case
    cloud = tmp_path / "big.npy"
    np.save(cloud, points.astype(np.float32))
    out = tmp_path / "m.obj"
    _register()
    result = CliRunner().invoke(app, ["generate", str(cloud), "-o", str(out), "--model",
                                      str(toy_repository), "--seed", str(seed),
                                      "--no-progress", "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["points_reduced"] == {"read": BIG, "used": 200_000}
    assert summary["faces"] > 0 and out.exists()
