"""The runtime image's environment, built the way the Dockerfile builds it, without Docker:
a fresh virtual environment, ``deploy/install.sh deps`` then ``app`` (the same requirement
files, the model and service packages without dependencies) in a copy of the build
context, then ``spacemesh serve`` from it answers ``/generate`` and passes the image's
HEALTHCHECK command. One environment per session; pip's cache is reused."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from deploy_testing import ROOT, free_port

pytestmark = pytest.mark.slow

#: What `.dockerignore` keeps out of the copied folders.
LEFTOVERS = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "build", "dist")


def run(command: list[str], cwd: Path, timeout: float = 900, **env: str) -> str:
    environment = {k: v for k, v in os.environ.items() if k != "PIP_NO_CACHE_DIR"}
    done = subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env={**environment, **env})
    assert done.returncode == 0, f"{' '.join(command)}:\n{done.stdout[-2000:]}{done.stderr[-3000:]}"
    return done.stdout


@pytest.fixture(scope="session")
def runtime_venv(tmp_path_factory) -> Path:
    """The image's /opt/venv, built here: a copy of the build context, then install.sh."""
    base = tmp_path_factory.mktemp("runtime-image")
    context = base / "src"  # the Dockerfile's WORKDIR /src
    (context / "deploy").mkdir(parents=True)
    for name in ("install.sh", "healthcheck.py"):
        shutil.copy(ROOT / "deploy" / name, context / "deploy" / name)
    for requirements in (ROOT / "deploy").glob("requirements-*.txt"):
        shutil.copy(requirements, context / "deploy" / requirements.name)
    for package in ("model", "service"):
        shutil.copytree(ROOT / package, context / package, ignore=LEFTOVERS)
    venv = base / "venv"
    # install.sh makes the venv with $PYTHON: this interpreter's version, as in the image
    run(["sh", "deploy/install.sh", "deps", str(venv), "cpu"], context, PYTHON=sys.executable)
    run(["sh", "deploy/install.sh", "app", str(venv)], context)
    return venv


def pinned_names() -> set[str]:
    """Normalised names pinned by the CPU image's requirement files."""
    names = set()
    for name in ("requirements-runtime.txt", "requirements-onnxruntime-cpu.txt"):
        text = (ROOT / "deploy" / name).read_text()
        names |= set(re.findall(r"^([A-Za-z0-9_.-]+)==", text, re.M))
    return {re.sub(r"[-_.]+", "-", n).lower() for n in names}


def test_the_environment_is_pinned_and_has_no_torch(runtime_venv):
    python = str(runtime_venv / "bin" / "python")
    run([python, "-m", "pip", "check"], ROOT)
    freeze = run([python, "-m", "pip", "list", "--format", "freeze"], ROOT)
    installed = {re.sub(r"[-_.]+", "-", line.split("==")[0]).lower()
                 for line in freeze.splitlines() if "==" in line}
    ours = {"spacemesh", "spacemesh-service", "pip"}
    assert installed - ours <= pinned_names(), installed - ours - pinned_names()
    for absent in ("torch", "setuptools", "wheel", "spacemesh_client", "trimesh"):
        done = subprocess.run([python, "-c", f"import {absent}"], capture_output=True)
        assert done.returncode != 0, f"{absent} is in the runtime environment"


def test_spacemesh_serve_answers_generate(runtime_venv, toy_repository, case, tmp_path):
    port, grpc_port = free_port(), free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPACEMESH_")}
    env.update(SPACEMESH_PORT=str(port), SPACEMESH_GRPC_PORT=str(grpc_port),
               SPACEMESH_HOST="127.0.0.1", SPACEMESH_ORT_THREADS="1",
               PATH=f"{runtime_venv / 'bin'}{os.pathsep}{env.get('PATH', '')}")
    env.pop("PYTHONPATH", None)
    healthcheck = [str(runtime_venv / "bin" / "python"), str(ROOT / "deploy" / "healthcheck.py")]
    assert subprocess.run(healthcheck, env=env, capture_output=True).returncode == 1  # no server
    log = (tmp_path / "serve.log").open("w")
    process = subprocess.Popen(["spacemesh", "serve", "--model", str(toy_repository)],
                               cwd=tmp_path, env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        while subprocess.run(healthcheck, env=env, capture_output=True).returncode != 0:
            assert process.poll() is None, (tmp_path / "serve.log").read_text()
            assert time.monotonic() < deadline, (tmp_path / "serve.log").read_text()
            time.sleep(0.2)
        # a closed surface asked for: whether the tiny model's few faces read as an open
        # scan (surface=auto) is not what this test is about
        body = {"points": case.points.tolist(), "seed": case.good_seed, "format": "obj",
                "surface": "closed"}
        response = httpx.post(url + "/generate", json=body, timeout=60)
        assert response.status_code == 200, response.text
        assert response.headers["x-spacemesh-closed"] == "true"
        from spacemesh_client import Client

        with Client(f"grpc://127.0.0.1:{grpc_port}") as client:  # gRPC works there too
            mesh = client.generate(case.points, seed=case.good_seed, format="obj",
                                   surface="closed")
        assert mesh.data == response.content
        process.send_signal(signal.SIGTERM)
        assert process.wait(60) == 0  # drains and exits cleanly, as `docker stop` expects
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        log.close()
