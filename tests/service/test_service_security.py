"""Protection on real servers over both protocols: API keys, rate limits, TLS, access logs
and request ids, header / body / idle timeouts, start-up refusals, metadata without paths.
"""

from __future__ import annotations

import asyncio
import datetime
import hashlib
import ipaddress
import json
import logging
import socket
import ssl
import subprocess
import sys
import time

import grpc
import httpx
import pytest
from grpc_health.v1 import health_pb2, health_pb2_grpc
from service_testing import server_settings

from spacemesh_service.access_log import ACCESS_LOGGER
from spacemesh_service.pb import spacemesh_pb2 as pb
from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc
from spacemesh_service.security import (
    ConfigError,
    Guard,
    RateLimiter,
    client_address,
    looks_like_path,
    parse_networks,
    without_paths,
)
from spacemesh_service.server import SpaceMeshServer

pytestmark = pytest.mark.slow

PROBLEMS = "https://spacemesh.dev/problems/"
#: One key per test that spends rate-limit tokens, so the tests do not share buckets.
KEYS = {name: f"key-{name}-{hashlib.sha256(name.encode()).hexdigest()[:16]}"
        for name in ("rest", "grpc", "sdk", "cli", "log", "limit-rest", "limit-grpc",
                     "metrics")}
#: A generous bound for "the server closes it" waits (not a timing assertion: it only
#: keeps a broken server from hanging the test).
CLOSE_WAIT_S = 20.0


def key_id(key: str) -> str:
    return hashlib.sha256(key.encode()).hexdigest()[:12]


def bearer(key: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}"}


def walk_strings(value):
    if isinstance(value, dict):
        for item in value.values():
            yield from walk_strings(item)
    elif isinstance(value, list):
        for item in value:
            yield from walk_strings(item)
    elif isinstance(value, str):
        yield value


def points_request(points, **options) -> pb.GenerateRequest:
    return pb.GenerateRequest(points=pb.Points(xyz=points.ravel().tolist()), **options)


# ---------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def key_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("keys") / "api-keys"
    path.write_text("# SpaceMesh API keys\n\n" + "\n".join(f"  {k}  " for k in KEYS.values())
                    + "\n# the end\n")
    return path


@pytest.fixture(scope="module")
def guarded(start_server, generator, key_file):
    """Keys on, and a rate limit of 3 requests per key (refilled once in 1000 s)."""
    return start_server(generator, api_keys=key_file, rate_limit=0.001, rate_burst=3)


@pytest.fixture(scope="module")
def model_name(guarded):
    return guarded.server.engine.model_name


@pytest.fixture
def access_lines(caplog):
    """The access lines logged during a test, as dicts (waits for ``count`` of them)."""
    caplog.set_level(logging.INFO, logger=ACCESS_LOGGER)

    def lines(count: int = 1, **match) -> list[dict]:
        deadline = time.monotonic() + CLOSE_WAIT_S
        while True:
            found = [json.loads(r.getMessage()) for r in caplog.records
                     if r.name == ACCESS_LOGGER]
            found = [f for f in found if all(f.get(k) == v for k, v in match.items())]
            if len(found) >= count or time.monotonic() > deadline:
                return found
            time.sleep(0.02)

    return lines


def make_certificate(directory):
    """A self-signed certificate for 127.0.0.1 / localhost and its key (PEM files)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (
        x509.CertificateBuilder().subject_name(name).issuer_name(name)
        .public_key(key.public_key()).serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(x509.SubjectAlternativeName([
            x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
            critical=False)
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .sign(key, hashes.SHA256())
    )
    cert_path, key_path = directory / "cert.pem", directory / "key.pem"
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_path.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                           serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return cert_path, key_path


@pytest.fixture(scope="module")
def certificate(tmp_path_factory):
    return make_certificate(tmp_path_factory.mktemp("tls"))


# ---------------------------------------------------------------------- API keys
def test_rest_needs_a_right_key_but_health_stays_open(guarded, model_name):
    with httpx.Client(base_url=guarded.url, timeout=60) as http:
        for path in ("/v2/health/live", "/v2/health/ready", "/", "/static/config.json"):
            assert http.get(path).status_code == 200, path  # health and the web page
        route = f"/v2/models/{model_name}"
        for headers in ({}, bearer("not-a-key"), {"Authorization": f"Basic {KEYS['rest']}"}):
            refused = http.get(route, headers=headers)
            assert refused.status_code == 401, headers
            assert refused.headers["content-type"].startswith("application/problem+json")
            assert refused.json()["type"] == PROBLEMS + "unauthorized"
            assert refused.headers["www-authenticate"].startswith("Bearer")
            assert ("invalid_token" in refused.headers["www-authenticate"]) == (
                headers == bearer("not-a-key"))
        for path in ("/metrics", "/v2", "/openapi.json"):
            assert http.get(path).status_code == 401, path
        refused = http.post("/generate", json={"points": [[0, 0, 0]] * 20})
        assert refused.status_code == 401  # refused before the body is parsed
        assert http.get(route, headers=bearer(KEYS["rest"])).status_code == 200


def test_grpc_needs_a_right_key_but_health_stays_open(guarded, case):
    with grpc.insecure_channel(guarded.grpc_target) as channel:
        health = health_pb2_grpc.HealthStub(channel).Check(health_pb2.HealthCheckRequest())
        assert health.status == health_pb2.HealthCheckResponse.SERVING
        stub = pb_grpc.SpaceMeshStub(channel)
        request = points_request(case.points, seed=case.good_seed)
        for metadata in ((), (("authorization", "Bearer not-a-key"),)):
            with pytest.raises(grpc.RpcError) as info:
                stub.Generate(request, metadata=metadata)
            assert info.value.code() == grpc.StatusCode.UNAUTHENTICATED
            trailing = dict(info.value.trailing_metadata())
            assert trailing["problem-type"] == PROBLEMS + "unauthorized"
            assert trailing["problem-status"] == "401"
            assert trailing["x-request-id"]
        with pytest.raises(grpc.RpcError) as info:  # streams too
            next(iter(stub.GenerateStream(request)))
        assert info.value.code() == grpc.StatusCode.UNAUTHENTICATED
        reply = stub.Generate(request, metadata=(("authorization", f"Bearer {KEYS['grpc']}"),))
        assert reply.stats.faces > 0


def test_the_sdk_sends_its_key_over_both_transports(guarded, case, monkeypatch):
    from spacemesh_client import Client
    from spacemesh_client.errors import Unauthorized
    from spacemesh_client.retry import RetryPolicy

    for url in (guarded.url, f"grpc://{guarded.grpc_target}"):
        monkeypatch.delenv("SPACEMESH_API_KEY", raising=False)
        with Client(url, retry=RetryPolicy.never()) as client:
            with pytest.raises(Unauthorized):
                client.generate(case.points, seed=case.good_seed)
        monkeypatch.setenv("SPACEMESH_API_KEY", KEYS["sdk"])  # the environment's key
        with Client(url, retry=RetryPolicy.never()) as client:
            assert client.generate(case.points, seed=case.good_seed).stats.faces > 0


def test_the_client_cli_takes_a_key(guarded, model_name, monkeypatch, capsys):
    from spacemesh_client.cli import main

    monkeypatch.delenv("SPACEMESH_API_KEY", raising=False)
    with pytest.raises(SystemExit) as info:
        main(["info", model_name, "--url", guarded.url, "--retries", "0"])
    assert info.value.code == 2
    assert "401" in capsys.readouterr().err.strip()
    main(["info", model_name, "--url", guarded.url, "--api-key", KEYS["cli"]])
    assert "limits" in json.loads(capsys.readouterr().out)


def test_metrics_take_a_key_or_a_flag(guarded, start_server, generator, key_file):
    with httpx.Client(base_url=guarded.url) as http:
        assert http.get("/metrics").status_code == 401
        assert http.get("/metrics", headers=bearer(KEYS["metrics"])).status_code == 200
    public = start_server(generator, api_keys=key_file, public_metrics=True)
    with httpx.Client(base_url=public.url) as http:
        assert http.get("/metrics").status_code == 200
        assert http.get("/v2").status_code == 401


def test_an_empty_key_file_is_refused_at_start(tmp_path, toy_repository):
    empty = tmp_path / "keys"
    empty.write_text("# no keys yet\n\n   \n")
    with pytest.raises(ConfigError, match="has no key"):
        SpaceMeshServer(server_settings(toy_repository, api_keys=empty))
    with pytest.raises(ConfigError, match="cannot read"):
        SpaceMeshServer(server_settings(toy_repository, api_keys=tmp_path / "missing"))


def serve_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", "from spacemesh.cli import main; main()", "serve", "--port",
         "0", "--grpc-port", "0", "--host", "127.0.0.1", *args],
        capture_output=True, text=True, timeout=120)


def test_spacemesh_serve_refuses_bad_protection_settings_in_one_line(tmp_path, toy_repository,
                                                                     certificate):
    empty = tmp_path / "keys"
    empty.write_text("\n# nothing\n")
    cert, _ = certificate
    cases = {
        "has no key": ["--api-keys", str(empty)],
        "give both or neither": ["--tls-cert", str(cert)],
        "is not an IP address or CIDR": ["--trusted-proxies", "10.0.0.0/8,proxy.local"],
        "cannot use the certificate": ["--tls-cert", str(cert), "--tls-key", str(empty)],
    }
    for message, args in cases.items():
        done = serve_cli("--model", str(toy_repository), *args)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2, (args, done.stderr)
        assert len(lines) == 1 and message in lines[0], (args, done.stderr)
        assert "Traceback" not in done.stderr


# ---------------------------------------------------------------------- rate limits
def test_rest_rate_limit_answers_429_with_retry_after(guarded, model_name):
    route, headers = f"/v2/models/{model_name}", bearer(KEYS["limit-rest"])
    with httpx.Client(base_url=guarded.url) as http:
        statuses = [http.get(route, headers=headers).status_code for _ in range(3)]
        assert statuses == [200, 200, 200]  # the burst
        limited = http.get(route, headers=headers)
        assert limited.status_code == 429
        assert limited.json()["type"] == PROBLEMS + "rate-limited"
        assert int(limited.headers["retry-after"]) >= 1
        assert http.get("/v2/health/ready").status_code == 200  # health is not counted
        # another key has its own bucket
        assert http.get(route, headers=bearer(KEYS["metrics"])).status_code == 200


def test_grpc_rate_limit_is_resource_exhausted_with_retry_after(guarded, case):
    metadata = (("authorization", f"Bearer {KEYS['limit-grpc']}"),)
    with grpc.insecure_channel(guarded.grpc_target) as channel:
        stub = pb_grpc.SpaceMeshStub(channel)
        request = pb.GenerateRequest()  # no input: refused (400) after the guard
        for _ in range(3):
            with pytest.raises(grpc.RpcError) as info:
                stub.Generate(request, metadata=metadata)
            assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
        with pytest.raises(grpc.RpcError) as info:
            stub.Generate(request, metadata=metadata)
        assert info.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED
        trailing = dict(info.value.trailing_metadata())
        assert trailing["problem-type"] == PROBLEMS + "rate-limited"
        assert int(trailing["retry-after"]) >= 1


def test_rate_limits_by_forwarded_address_only_behind_a_trusted_proxy(start_server,
                                                                       generator):
    trusting = start_server(generator, rate_limit=0.001, rate_burst=1,
                            trusted_proxies="127.0.0.0/8")
    trusting_none = start_server(generator, rate_limit=0.001, rate_burst=1)
    with httpx.Client(base_url=trusting.url) as http:
        first = {"X-Forwarded-For": "203.0.113.7"}
        assert http.get("/v2", headers=first).status_code == 200
        assert http.get("/v2", headers=first).status_code == 429
        # a client behind the proxy that forges a first hop is still counted by the
        # address the proxy appended
        forged = {"X-Forwarded-For": "198.51.100.1, 203.0.113.7"}
        assert http.get("/v2", headers=forged).status_code == 429
        assert http.get("/v2", headers={"X-Forwarded-For": "203.0.113.8"}).status_code == 200
        # a second header line (another proxy's) counts: its address is the right-most
        two_lines = [("X-Forwarded-For", "198.51.100.2"), ("X-Forwarded-For", "203.0.113.8")]
        assert http.get("/v2", headers=two_lines).status_code == 429
    with httpx.Client(base_url=trusting_none.url) as http:
        assert http.get("/v2", headers={"X-Forwarded-For": "203.0.113.9"}).status_code == 200
        # the header is ignored: the same peer address, whatever it says
        assert http.get("/v2", headers={"X-Forwarded-For": "203.0.113.10"}).status_code == 429


def test_client_address_and_token_bucket():
    trusted = parse_networks("10.0.0.0/8, 127.0.0.1")
    assert client_address("127.0.0.1", "1.2.3.4, 10.1.1.1", trusted) == "1.2.3.4"
    assert client_address("192.0.2.1", "1.2.3.4", trusted) == "192.0.2.1"
    assert client_address("127.0.0.1", "not-an-ip", trusted) == "127.0.0.1"
    assert client_address("127.0.0.1", "1.2.3.4", ()) == "127.0.0.1"
    now = [0.0]
    limiter = RateLimiter(2.0, 2, max_clients=2, clock=lambda: now[0])
    assert [limiter.take("a") for _ in range(2)] == [0, 0]
    assert limiter.take("a") == pytest.approx(0.5)
    now[0] += 0.5
    assert limiter.take("a") == 0
    for client in ("b", "c", "d"):  # bounded memory: a is forgotten
        limiter.take(client)
    assert len(limiter._buckets) == 2
    assert Guard(public_metrics=True).is_open("/metrics")
    assert not Guard().is_open("/metrics")


# ---------------------------------------------------------------------- TLS
def test_tls_serves_rest_and_grpc_with_one_certificate(start_server, generator, case,
                                                       certificate, key_file):
    cert, key = certificate
    served = start_server(generator, tls_cert=cert, tls_key=key)
    assert served.url.startswith("https://")
    context = ssl.create_default_context(cafile=str(cert))
    with httpx.Client(base_url=served.url, verify=context) as http:
        assert http.get("/v2/health/ready").status_code == 200
    with pytest.raises(httpx.ConnectError):  # the system's CAs do not know it
        httpx.get(served.url + "/v2/health/ready")
    plain = served.url.replace("https://", "http://")
    with pytest.raises(httpx.HTTPError):
        httpx.get(plain + "/v2/health/ready")
    credentials = grpc.ssl_channel_credentials(root_certificates=cert.read_bytes())
    with grpc.secure_channel(served.grpc_target, credentials) as channel:
        reply = pb_grpc.SpaceMeshStub(channel).Generate(
            points_request(case.points, seed=case.good_seed))
        assert reply.stats.faces > 0
    with grpc.insecure_channel(served.grpc_target) as channel:  # plaintext is refused
        with pytest.raises(grpc.RpcError) as info:
            health_pb2_grpc.HealthStub(channel).Check(health_pb2.HealthCheckRequest(),
                                                      timeout=10)
        assert info.value.code() == grpc.StatusCode.UNAVAILABLE

    from spacemesh_client import Client

    target = served.grpc_target
    for url in (served.url, f"grpcs://{target}"):
        with Client(url, verify=cert) as client:
            assert client.health().ready
            assert client.generate(case.points, seed=case.good_seed).stats.faces > 0


def test_tls_needs_both_files(certificate, toy_repository):
    _, key = certificate
    with pytest.raises(ValueError, match="give both or neither"):
        server_settings(toy_repository, tls_key=key)


# ---------------------------------------------------------------------- access logs
def test_rest_access_log_line_and_request_id(guarded, model_name, access_lines):
    key = KEYS["log"]
    with httpx.Client(base_url=guarded.url) as http:
        answer = http.get(f"/v2/models/{model_name}",
                          headers={**bearer(key), "X-Request-ID": "trace-42.a:b"})
        assert answer.status_code == 200
        assert answer.headers["x-request-id"] == "trace-42.a:b"
        refused = http.get("/v2", headers={"X-Request-ID": "x" * 500})
        generated = refused.headers["x-request-id"]
        assert len(generated) == 32 and generated != "x" * 500
    [line] = access_lines(request_id="trace-42.a:b")
    assert line["route"] == "/v2/models/{name}" and line["path"] == f"/v2/models/{model_name}"
    assert line["status"] == 200 and line["bytes"] == len(answer.content)
    assert line["client"] == "127.0.0.1" and line["method"] == "GET"
    assert line["key"] == key_id(key) and line["ms"] >= 0
    [refused_line] = access_lines(request_id=generated)
    assert refused_line["status"] == 401 and refused_line["key"] is None
    assert key not in json.dumps(access_lines(0))


def test_grpc_access_log_line_and_request_id(guarded, case, access_lines):
    key = KEYS["log"]
    metadata = (("authorization", f"Bearer {key}"), ("x-request-id", "grpc-trace-7"))
    with grpc.insecure_channel(guarded.grpc_target) as channel:
        stub = pb_grpc.SpaceMeshStub(channel)
        reply, call = stub.Generate.with_call(
            points_request(case.points, seed=case.good_seed), metadata=metadata)
        assert dict(call.trailing_metadata())["x-request-id"] == "grpc-trace-7"
        with pytest.raises(grpc.RpcError) as info:  # an error keeps the id too
            stub.Generate(pb.GenerateRequest(),
                          metadata=(*metadata[:1], ("x-request-id", "grpc-trace-8")))
        trailing = dict(info.value.trailing_metadata())
        assert trailing["x-request-id"] == "grpc-trace-8"
        assert trailing["problem-type"] == PROBLEMS + "malformed-input"
    [line] = access_lines(request_id="grpc-trace-7")
    assert line["transport"] == "grpc" and line["status"] == "OK"
    assert line["route"] == "/spacemesh.v1.SpaceMesh/Generate"
    assert line["bytes"] == reply.ByteSize() and line["key"] == key_id(key)
    assert line["client"] == "127.0.0.1"
    [failed] = access_lines(request_id="grpc-trace-8")
    assert failed["status"] == "INVALID_ARGUMENT"


def test_the_default_log_level_shows_access_lines(capfd):
    from spacemesh_service.access_log import log_request
    from spacemesh_service.server import configure_logging
    from spacemesh_service.settings import Settings

    loggers = [logging.getLogger(name) for name in (ACCESS_LOGGER, "spacemesh.service")]
    saved = [(lg.handlers[:], lg.level, lg.propagate) for lg in loggers]
    try:
        configure_logging(Settings().log_level)
        log_request(request_id="r1", status=200)
        assert json.loads(capfd.readouterr().out.strip()) == {"request_id": "r1", "status": 200}
    finally:
        for lg, (handlers, level, propagate) in zip(loggers, saved, strict=True):
            lg.handlers[:], lg.level, lg.propagate = handlers, level, propagate


# ---------------------------------------------------------------------- timeouts
@pytest.fixture(scope="module")
def impatient(start_server, generator):
    return start_server(generator, header_timeout_s=0.5, body_timeout_s=1.0,
                        idle_timeout_s=0.5, grpc_idle_timeout_s=0.5)


def connect(server) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", server.server.http_port), timeout=CLOSE_WAIT_S)
    return sock


def read_until_closed(sock: socket.socket) -> bytes:
    """Everything the server sends until it closes the connection (socket.timeout if it
    never does)."""
    data = b""
    while chunk := sock.recv(65536):
        data += chunk
    return data


def test_a_connection_that_sends_no_headers_is_closed(impatient):
    with connect(impatient) as silent, connect(impatient) as partial:
        partial.sendall(b"GET /v2/health/live HTTP/1.1\r\nHost: x\r\n")  # never ends
        assert read_until_closed(silent) == b""
        assert read_until_closed(partial) == b""
    grpc_port = impatient.server.grpc_port
    with socket.create_connection(("127.0.0.1", grpc_port), timeout=CLOSE_WAIT_S) as silent:
        read_until_closed(silent)  # the server's SETTINGS, then the end (the handshake limit)


def test_an_idle_keep_alive_connection_is_closed(impatient):
    with connect(impatient) as sock:
        sock.sendall(b"GET /v2/health/live HTTP/1.1\r\nHost: x\r\n\r\n")
        answer = read_until_closed(sock)
    assert answer.startswith(b"HTTP/1.1 200") and answer.endswith(b'{"live":true}')


def test_a_trickled_body_gets_408(impatient):
    with connect(impatient) as sock:
        sock.sendall(b"POST /generate HTTP/1.1\r\nHost: x\r\nContent-Type: application/json"
                     b"\r\nContent-Length: 100000\r\n\r\n{\"points\": [")
        sock.settimeout(0.2)
        answer = b""
        deadline = time.monotonic() + CLOSE_WAIT_S
        while time.monotonic() < deadline:
            try:
                sock.sendall(b"[0, 0, 0],")
                chunk = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:  # closed while sending
                break
            if not chunk:
                break
            answer += chunk
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 408"), answer[:200]
    assert b"connection: close" in head.lower()
    assert b"application/problem+json" in head
    assert json.loads(body)["type"] == PROBLEMS + "request-timeout"


def test_requests_within_the_timeouts_still_work(impatient, case):
    with httpx.Client(base_url=impatient.url, timeout=60) as http:
        answer = http.post("/generate", params={"seed": case.good_seed, "format": "json"},
                           json={"points": case.points.tolist()})
        assert answer.status_code == 200


def test_grpc_closes_idle_connections(impatient):
    async def states() -> list:
        async with grpc.aio.insecure_channel(impatient.grpc_target) as channel:
            await health_pb2_grpc.HealthStub(channel).Check(health_pb2.HealthCheckRequest())
            seen = [channel.get_state()]
            deadline = time.monotonic() + CLOSE_WAIT_S
            while seen[-1] == grpc.ChannelConnectivity.READY and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
                seen.append(channel.get_state())
            return seen

    seen = asyncio.run(states())
    assert seen[0] == grpc.ChannelConnectivity.READY
    assert seen[-1] == grpc.ChannelConnectivity.IDLE  # the server sent GOAWAY


def test_the_servers_are_configured_from_the_settings(toy_repository, impatient):
    from spacemesh_service.connections import grpc_options

    config = impatient.server._uvicorn.config
    assert config.timeout_keep_alive == 0.5 and config.http.header_timeout == 0.5
    assert config.proxy_headers is False  # X-Forwarded-For only from --trusted-proxies

    options = dict(grpc_options(server_settings(
        toy_repository, header_timeout_s=3, grpc_idle_timeout_s=7, grpc_keepalive_s=11,
        grpc_keepalive_timeout_s=13, grpc_max_connection_age_s=17, drain_timeout_s=19)))
    assert options == {
        "grpc.server_handshake_timeout_ms": 3000, "grpc.max_connection_idle_ms": 7000,
        "grpc.keepalive_time_ms": 11000, "grpc.keepalive_timeout_ms": 13000,
        "grpc.keepalive_permit_without_calls": 1, "grpc.max_connection_age_ms": 17000,
        "grpc.max_connection_age_grace_ms": 19000}


# ---------------------------------------------------------------------- OpenAPI
def test_openapi_documents_the_protection(guarded, impatient):
    with httpx.Client(base_url=guarded.url) as http:
        spec = http.get("/openapi.json", headers=bearer(KEYS["rest"])).json()
    assert spec["components"]["securitySchemes"]["apiKey"]["scheme"] == "bearer"
    generate = spec["paths"]["/generate"]["post"]
    assert generate["security"] == [{"apiKey": []}]
    assert {"401", "408", "429"} <= set(generate["responses"])
    assert "Retry-After" in generate["responses"]["429"]["headers"]
    ready = spec["paths"]["/v2/health/ready"]["get"]
    assert "security" not in ready and "401" not in ready["responses"]
    with httpx.Client(base_url=impatient.url) as http:
        plain = http.get("/openapi.json").json()
    assert "securitySchemes" not in plain.get("components", {})
    responses = plain["paths"]["/generate"]["post"]["responses"]
    assert "408" in responses and not {"401", "429"} & set(responses)


# ---------------------------------------------------------------------- metadata
@pytest.fixture(scope="module")
def trained_here(toy_repository, tmp_path_factory):
    """The toy model, its manifest recording where it was trained (as real exports do:
    the shipped one names ``runs/.../last.pt``)."""
    import shutil

    copy = tmp_path_factory.mktemp("model") / toy_repository.name
    shutil.copytree(toy_repository, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["training"]["run"] = "/home/alice/spacemesh/runs/tiny"
    manifest["data"]["init"] = {"checkpoint": "runs/tiny/checkpoints/last.pt", "steps": 4}
    (copy / "manifest.json").write_text(json.dumps(manifest))
    return copy


def test_metadata_shows_no_file_system_paths(start_server, trained_here):
    served = start_server(model=trained_here)
    raw = served.server.engine.metadata()
    assert {"/home/alice/spacemesh/runs/tiny", "runs/tiny/checkpoints/last.pt"} <= set(
        walk_strings(raw))
    name = served.server.engine.model_name
    with httpx.Client(base_url=served.url) as http:
        shown = http.get(f"/v2/models/{name}").json()
        assert http.get(f"/v2/models/{name}/versions/{served.server.engine.model_version}"
                        ).json() == shown
    assert not [s for s in walk_strings(shown) if looks_like_path(s)]
    assert str(trained_here) not in json.dumps(shown) and "alice" not in json.dumps(shown)
    assert shown["data"]["init"] == {"steps": 4}  # the rest of the member stays
    assert shown["output_formats"] == raw["output_formats"]  # media types are kept
    assert shown["limits"] == raw["limits"] and shown["training"]["steps"] == 4


def test_the_shipped_manifest_paths_are_stripped():
    from spacemesh.runtime.repository import default_model_dir

    manifests = sorted(default_model_dir().glob("*/manifest.json"))
    assert manifests
    manifest = json.loads(manifests[-1].read_text())
    paths = [s for s in walk_strings(manifest) if looks_like_path(s)]
    assert paths, "the shipped manifest names training runs (the case this guards)"
    assert not [s for s in walk_strings(without_paths(manifest)) if looks_like_path(s)]
    for text in ("model/gltf-binary", "application/json", "https://spacemesh.dev/x/y",
                 "ddim", "a b/c/d"):
        assert not looks_like_path(text), text
    for text in ("/srv/models/x", "runs/a/checkpoints/last.pt", "C:\\data\\x", "x/last.pt"):
        assert looks_like_path(text), text
