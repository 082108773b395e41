"""``spacemesh serve`` as a separate process: no torch, SIGTERM drain, a corrupt model."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

pytestmark = pytest.mark.slow

#: Runs the real command line (``spacemesh serve ...`` via ``main()``).
CLI = "from spacemesh.cli import main; main()"

#: A sitecustomize that makes this Python behave as if torch were not installed, and
#: writes down every attempt to import it.
NO_TORCH = textwrap.dedent('''
    import os, sys

    class _NoTorch:
        def find_spec(self, name, path=None, target=None):
            if name == "torch" or name.startswith("torch."):
                with open(os.environ["TORCH_ATTEMPTS"], "a") as log:
                    log.write(name + "\\n")
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, _NoTorch())
''')

#: Each batch sleeps first, so a request is surely in flight when SIGTERM arrives.
SLOW_CLI = textwrap.dedent('''
    import time
    from spacemesh.runtime.pipeline import MeshGenerator
    _inner = MeshGenerator.generate_batch
    def _slow(self, requests, **kw):
        time.sleep(2.0)
        return _inner(self, requests, **kw)
    MeshGenerator.generate_batch = _slow
    from spacemesh.cli import main
    main()
''')


class Served:
    """A ``spacemesh serve`` subprocess; its stderr is collected in the background."""

    def __init__(self, code: str, args: list[str], env: dict[str, str] | None = None,
                 threads: int = 1) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-c", code, "serve", "--port", "0", "--grpc-port", "0",
             "--ort-threads", str(threads), "--host", "127.0.0.1", *args],
            env={**os.environ, **(env or {})}, stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stderr:
            self.lines.append(line)

    @property
    def log(self) -> str:
        return "".join(self.lines)

    def url(self, timeout: float = 120) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            match = re.search(r"listening: rest=(http://\S+)", self.log)
            if match:
                return match.group(1)
            assert self.process.poll() is None, self.log
            time.sleep(0.05)
        raise AssertionError("the server did not start:\n" + self.log)

    def wait_ready(self, timeout: float = 120) -> str:
        url = self.url(timeout)
        deadline = time.monotonic() + timeout
        while httpx.get(url + "/v2/health/ready").status_code != 200:
            assert self.process.poll() is None, self.log
            assert time.monotonic() < deadline, self.log
            time.sleep(0.05)
        return url

    def stop(self) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            return self.process.wait(60)
        finally:
            self._reader.join(5)


@pytest.fixture
def served():
    started: list[Served] = []

    def start(*args, **kwargs) -> Served:
        started.append(Served(*args, **kwargs))
        return started[-1]

    yield start
    for process in started:
        if process.process.poll() is None:
            process.process.kill()
            process.process.wait()


def test_serves_without_torch(tmp_path, served, toy_repository, case, http):
    (tmp_path / "sitecustomize.py").write_text(NO_TORCH)
    attempts = tmp_path / "torch-attempts.txt"
    env = {"PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]),
           "TORCH_ATTEMPTS": str(attempts)}
    check = subprocess.run(
        [sys.executable, "-c", "import torch"], env={**os.environ, **env},
        capture_output=True, text=True)
    assert check.returncode != 0 and "ModuleNotFoundError" in check.stderr  # the block works
    attempts.unlink()
    process = served(CLI, ["--model", str(toy_repository)], env=env)
    url = process.wait_ready()
    body = {"points": case.points.tolist(), "seed": case.good_seed, "format": "obj"}
    response = httpx.post(url + "/generate", json=body, timeout=60)
    assert response.status_code == 200, response.text
    assert response.content == http.post("/generate", json=body).content
    assert process.stop() == 0
    assert not attempts.exists(), attempts.read_text()  # nothing even tried to import torch


def test_sigterm_drains_in_flight_requests(served, toy_repository, case):
    process = served(SLOW_CLI, ["--model", str(toy_repository), "--no-warmup"])
    url = process.wait_ready()
    body = {"points": case.points.tolist(), "seed": case.good_seed, "format": "ply"}
    with ThreadPoolExecutor(1) as pool:
        pending = pool.submit(httpx.post, url + "/generate", json=body, timeout=60)
        deadline = time.monotonic() + 30
        while "spacemesh_inflight_requests 1.0" not in httpx.get(url + "/metrics").text:
            assert time.monotonic() < deadline and not pending.done()
            time.sleep(0.01)
        process.process.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + 30
        while "draining" not in process.log:
            assert time.monotonic() < deadline, process.log
            time.sleep(0.01)
        # a request that arrives during the drain gets an answer to retry elsewhere
        late = httpx.post(url + "/generate", json=body, timeout=60)
        ready = httpx.get(url + "/v2/health/ready")
        grpc_status = _grpc_health(process.log)
        response = pending.result()
    assert late.status_code == 503, late.text
    assert late.json()["type"].endswith("shutting-down") and late.headers["retry-after"]
    assert ready.status_code == 503
    from grpc_health.v1 import health_pb2

    assert grpc_status == health_pb2.HealthCheckResponse.NOT_SERVING
    assert response.status_code == 200, response.text + process.log
    assert response.headers["x-spacemesh-closed"] == "true"
    assert process.process.wait(60) == 0
    with pytest.raises(httpx.ConnectError):
        httpx.get(url + "/v2/health/live")


def _grpc_health(log: str) -> int:
    """grpc.health.v1's status of the server whose log is ``log``."""
    import grpc
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    address = re.search(r"grpc=(\S+)", log).group(1)
    with grpc.insecure_channel(address) as channel:
        reply = health_pb2_grpc.HealthStub(channel).Check(
            health_pb2.HealthCheckRequest(service=""), timeout=10)
    return reply.status


def test_a_request_just_after_sigterm_gets_503_when_nothing_is_in_flight(
        served, toy_repository, case):
    process = served(CLI, ["--model", str(toy_repository), "--no-warmup",
                           "--drain-notice-s", "3"])
    url = process.wait_ready()
    process.process.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + 30
    while "draining" not in process.log:
        assert time.monotonic() < deadline, process.log
        time.sleep(0.01)
    late = httpx.post(url + "/generate", json={"points": case.points.tolist()}, timeout=60)
    assert late.status_code == 503 and late.json()["type"].endswith("shutting-down")
    assert process.process.wait(60) == 0


def test_a_corrupt_model_stops_the_server(tmp_path, served, toy_repository):
    copy = tmp_path / "model"
    shutil.copytree(toy_repository, copy)
    encoder = Path(copy / "encoder.onnx")
    encoder.write_bytes(encoder.read_bytes() + b"\0")
    process = served(CLI, ["--model", str(copy)])
    assert process.process.wait(120) == 1
    process._reader.join(5)
    assert "does not match its manifest" in process.log


def test_a_missing_model_is_one_line(tmp_path):
    done = subprocess.run([sys.executable, "-c", CLI, "serve", "--model",
                           str(tmp_path / "nothing")], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip().startswith("spacemesh: error: model repository")
