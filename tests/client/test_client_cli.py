"""``spacemesh-client`` against a real server: generate, repair, health, info, and one-line
errors with exit code 2 (bad request) or 1 (server, connection)."""

from __future__ import annotations

import json
import subprocess
import sys

import httpx
import pytest
from service_testing import as_ply

from spacemesh_client.cli import main, region_of

pytestmark = pytest.mark.slow

#: The installed console script's code path, without relying on PATH.
CLI = [sys.executable, "-c", "from spacemesh_client.cli import main; main()"]


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120)


@pytest.fixture
def cloud(tmp_path, case):
    path = tmp_path / "cloud.ply"
    path.write_bytes(as_ply(case.points))
    return path


def test_generate_writes_the_servers_bytes(rest_url, grpc_url, cloud, case, tmp_path):
    out = tmp_path / "mesh.glb"
    done = run("generate", str(cloud), "-o", str(out), "--url", rest_url,
               "--seed", str(case.good_seed))
    assert done.returncode == 0, done.stderr
    assert "closed oriented manifold" in done.stdout and str(out) in done.stdout
    reference = httpx.post(rest_url + "/generate", params={"seed": case.good_seed},
                           files={"file": ("cloud.ply", cloud.read_bytes())}, timeout=60)
    assert out.read_bytes() == reference.content  # GLB asked from the extension
    grpc_out = tmp_path / "grpc.glb"
    done = run("generate", str(cloud), "-o", str(grpc_out), "--url", grpc_url,
               "--seed", str(case.good_seed), "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["seed"] == case.good_seed and summary["closed"] and summary["format"] == "glb"
    assert grpc_out.read_bytes() == out.read_bytes()


def test_the_url_comes_from_the_environment(rest_url, cloud, tmp_path, monkeypatch, case,
                                            capsys):
    monkeypatch.setenv("SPACEMESH_URL", rest_url)
    out = tmp_path / "mesh.stl"  # not a server format: PLY asked, converted when saved
    pytest.importorskip("trimesh")
    main(["generate", str(cloud), "-o", str(out), "--seed", str(case.good_seed), "--json"])
    assert json.loads(capsys.readouterr().out)["format"] == "ply"
    assert out.stat().st_size > 0


def test_clear_errors(rest_url, cloud, tmp_path, case):
    out = str(tmp_path / "mesh.obj")
    cases = [
        (["generate", str(tmp_path / "missing.ply"), "-o", out], 2, "missing.ply: no such file"),
        (["generate", str(cloud), "-o", str(tmp_path / "no" / "m.obj")], 2, "no such directory"),
        (["generate", str(cloud), "-o", str(tmp_path / "mesh")], 2, "extension"),
        (["generate", str(cloud), "-o", out, "--steps", "0", "--url", rest_url], 2,
         "An option is invalid (422): steps must be in"),
        (["generate", str(cloud), "-o", out, "--format", "obj", "--url", rest_url,
          "--samples", "17"], 2, "samples must be in 1..16, not 17"),
        (["generate", str(cloud), "-o", out, "--url", rest_url, "--start", "noise",
          "--start-time", "0.5"], 2, "start_time applies to start=points only"),
        (["generate", str(cloud), "-o", out, "--samples", "two"], 2,
         "argument --samples: samples must be an integer"),
        (["generate", str(cloud), "-o", out, "--seed", "1e3"], 2,
         "argument --seed: seed must be an integer (digits only, no fraction or exponent), "
         "not '1e3'"),
        (["generate", str(cloud), "-o", out, "--samples", "2.0"], 2,
         "argument --samples: samples must be an integer"),
        (["generate", str(cloud), "-o", out, "--target-vertices", "500.0"], 2,
         "argument --target-vertices: target_vertices must be an integer"),
        (["repair", str(cloud), "-o", out, "--seed", "1.0", "--faces", "1"], 2,
         "argument --seed: seed must be an integer"),
        (["generate", str(cloud), "-o", out, "--url", "ftp://x"], 2, "unsupported URL"),
        (["generate", str(cloud), "-o", out, "--url", "http://127.0.0.1:9", "--retries", "0"],
         1, "cannot reach http://127.0.0.1:9"),
        (["repair", str(cloud), "-o", out, "--url", rest_url], 2, "exactly one of --faces"),
        (["repair", str(cloud), "-o", out, "--faces", "1,x"], 2, "expected indices"),
    ]
    for args, code, message in cases:
        done = run(*args)
        assert done.returncode == code, (args, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("spacemesh-client: error: "), done.stderr
        assert message in lines[0], (args, lines[0])


def test_repair_health_and_info(rest_url, cloud, tmp_path, case, generator):
    mesh = tmp_path / "mesh.obj"
    assert run("generate", str(cloud), "-o", str(mesh), "--url", rest_url,
               "--seed", str(case.good_seed)).returncode == 0
    done = run("repair", str(mesh), "-o", str(tmp_path / "fixed.obj"), "--faces", "0",
               "--steps", "4", "--url", rest_url)  # more: tests/client/test_client_repair.py
    if done.returncode:  # a generated mesh: its region may be refused, in one line
        assert done.returncode == 2 and "(422)" in done.stderr, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1
    else:
        assert "faces re-generated" in done.stdout
    health = run("health", "--url", rest_url)
    assert health.returncode == 0 and json.loads(health.stdout)["ready"] is True
    info = run("info", generator.name, "--url", rest_url)
    assert info.returncode == 0 and json.loads(info.stdout)["name"] == generator.name


def test_region_options():
    def parse(*argv):
        from spacemesh_client.cli import build_parser

        return region_of(build_parser().parse_args(["repair", "m.obj", "-o", "o.obj", *argv]))

    assert parse("--faces", "1,3-5") == {"faces": [1, 3, 4, 5]}
    assert parse("--vertices", "7") == {"vertices": [7]}
    assert parse("--sphere", "0,1,2,0.5") == {"sphere": {"center": [0, 1, 2], "radius": 0.5}}
    assert parse("--box", "0,0,0,1,1,1") == {"box": {"min": [0, 0, 0], "max": [1, 1, 1]}}
    assert parse("--region", '{"faces": [2]}') == {"faces": [2]}
