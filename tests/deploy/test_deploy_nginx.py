"""deploy/nginx.conf with a real nginx in front of two real servers on loopback: REST and
gRPC (HTTP/2) requests are spread over both replicas, and a replica that answers 503 (not
ready) hands REST requests to the other. Only the addresses change (``spacemesh:PORT``
-> the two loopback servers, the listen ports -> free ones, paths -> a temporary folder).

Skipped without an ``nginx`` binary (Debian: ``apt-get install nginx``).
"""

from __future__ import annotations

import re
import socket
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
from deploy_testing import ROOT, executable, free_port
from service_testing import GatedGenerator

from spacemesh_client import Client, RetryPolicy

pytestmark = pytest.mark.slow

NGINX_CONF = (ROOT / "deploy" / "nginx.conf").read_text()


def render(folder, rest: list[str], grpc: list[str], rest_port: int, grpc_port: int) -> str:
    """deploy/nginx.conf with loopback addresses and temporary paths."""
    conf = NGINX_CONF
    conf = re.sub(r"server spacemesh:8000 ([^;]*);",
                  lambda m: "\n".join(f"server {a} {m.group(1)};" for a in rest), conf)
    conf = re.sub(r"server spacemesh:8001 ([^;]*);",
                  lambda m: "\n".join(f"server {a} {m.group(1)};" for a in grpc), conf)
    conf = conf.replace("listen 8000;", f"listen 127.0.0.1:{rest_port};")
    conf = conf.replace("listen 8001 http2;", f"listen 127.0.0.1:{grpc_port} http2;")
    conf = conf.replace("pid /tmp/nginx.pid;", f"pid {folder}/nginx.pid;")
    conf = conf.replace("access_log /dev/stdout combined;", f"access_log {folder}/access.log;")
    temp = "".join(f"    {kind}_temp_path {folder}/{kind};\n" for kind in
                   ("client_body", "proxy", "fastcgi", "uwsgi", "scgi"))
    return conf.replace("http {\n", "http {\n" + temp, 1)


def wait_for_port(port: int, process: subprocess.Popen, timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while True:
        assert process.poll() is None, process.stderr.read()
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        assert time.monotonic() < deadline, "nginx did not listen"
        time.sleep(0.05)


def requests_served(server, protocol: str) -> float:
    """Generate requests this replica answered with 200 / OK."""
    text = server.server.engine.metrics.render().decode()
    pattern = (rf'^spacemesh_requests_total\{{protocol="{protocol}",route="[^"]*[Gg]enerate",'
               r'status="(?:200|OK)"\} (\S+)$')
    return sum(float(v) for v in re.findall(pattern, text, re.M))


@pytest.fixture
def nginx(tmp_path):
    binary = executable("nginx")
    if binary is None:
        pytest.skip("no nginx binary (apt-get install nginx)")
    started: list[subprocess.Popen] = []

    def start(rest: list[str], grpc: list[str]) -> tuple[str, str]:
        rest_port, grpc_port = free_port(), free_port()
        conf = tmp_path / "nginx.conf"
        conf.write_text(render(tmp_path, rest, grpc, rest_port, grpc_port))
        check = subprocess.run([binary, "-t", "-p", str(tmp_path), "-c", str(conf)],
                               capture_output=True, text=True)
        assert check.returncode == 0, check.stderr
        process = subprocess.Popen([binary, "-p", str(tmp_path), "-c", str(conf), "-g",
                                    "daemon off;"], stderr=subprocess.PIPE, text=True)
        started.append(process)
        wait_for_port(rest_port, process)
        wait_for_port(grpc_port, process)
        return f"http://127.0.0.1:{rest_port}", f"grpc://127.0.0.1:{grpc_port}"

    yield start
    for process in started:
        process.terminate()
        process.wait(30)


def test_rest_and_grpc_are_balanced_over_the_replicas(nginx, start_server, generator, case):
    replicas = [start_server(generator) for _ in range(2)]
    rest_url, grpc_url = nginx([r.url.split("//")[1] for r in replicas],
                               [r.grpc_target for r in replicas])
    before = {p: [requests_served(r, p) for r in replicas] for p in ("http", "grpc")}
    meshes = []
    for url in (rest_url, grpc_url):
        with Client(url, retry=RetryPolicy.never()) as client, ThreadPoolExecutor(4) as pool:
            assert client.health().ready
            jobs = [pool.submit(client.generate, case.points, seed=case.good_seed)
                    for _ in range(8)]
            meshes += [job.result() for job in jobs]
    assert len({m.data for m in meshes}) == 1  # the same mesh from every replica
    for protocol in ("http", "grpc"):
        served = [requests_served(r, protocol) - b for r, b in zip(replicas, before[protocol],
                                                                    strict=True)]
        assert sum(served) == 8 and all(n >= 1 for n in served), (protocol, served)


def test_a_replica_that_is_not_ready_hands_rest_requests_over(nginx, start_server, generator,
                                                              case):
    loading = GatedGenerator(generator)  # its warm-up waits: 503 not-ready
    busy = start_server(loading, wait_ready=False, warmup=True, drain_timeout_s=1)
    ready = start_server(generator)
    try:
        rest_url, _ = nginx([busy.url.split("//")[1], ready.url.split("//")[1]],
                            [busy.grpc_target, ready.grpc_target])
        with Client(rest_url, retry=RetryPolicy.never()) as client:
            meshes = [client.generate(case.points, seed=case.good_seed) for _ in range(6)]
        assert all(m.stats.closed for m in meshes)  # no 503 reached the client
    finally:
        loading.gate.set()
