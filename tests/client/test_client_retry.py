"""Retries: a loading server (503 + Retry-After), a full queue, a server that starts late
(connection refused), a proxy's 429, timeouts; and the policy's arithmetic."""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest
from service_testing import ADMIT_ALL, GatedGenerator, server_settings

from spacemesh_client import AsyncClient, Client, RetryPolicy
from spacemesh_client import errors as E
from spacemesh_client.errors import parse_retry_after
from spacemesh_service.server import BackgroundServer

pytestmark = pytest.mark.slow


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def retries_logged(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "spacemesh_client"]


@pytest.mark.parametrize("transport", ["rest", "grpc"])
def test_a_loading_server_is_waited_for(start_server, generator, case, caplog, transport):
    gated = GatedGenerator(generator)  # the warm-up waits at the gate: 503 not-ready
    server = start_server(gated, wait_ready=False, warmup=True, drain_timeout_s=1)
    url = server.url if transport == "rest" else "grpc://" + server.grpc_target
    caplog.set_level(logging.INFO, logger="spacemesh_client")
    opened = threading.Timer(0.3, gated.gate.set)
    started = time.monotonic()
    try:
        with Client(url, retry=RetryPolicy(attempts=10, backoff=0.01)) as client:
            assert not client.health().ready
            opened.start()
            mesh = client.generate(case.points, seed=case.good_seed)
    finally:
        gated.gate.set()
        opened.cancel()
    assert mesh.stats.closed
    logged = retries_logged(caplog)
    assert logged and all("NotReady" in line for line in logged)
    # the server says Retry-After: 1, and the client waited that long (not 0.01 s)
    assert time.monotonic() - started >= 1.0 * len(logged)


def test_a_full_queue_is_queue_full_then_retried(start_server, generator, case):
    gated = GatedGenerator(generator)
    server = start_server(gated, warmup=False, max_batch_size=1, queue_size=1,
                          drain_timeout_s=1)
    with ThreadPoolExecutor(3) as pool, Client(server.url, retry=RetryPolicy.never()) as once:
        try:
            running = pool.submit(once.generate, case.points, seed=case.good_seed)
            assert gated.entered.wait(30)  # one in the batch ...
            queued = pool.submit(once.generate, case.points, seed=case.good_seed)
            deadline = time.monotonic() + 30
            while "spacemesh_queue_depth 1.0" not in httpx.get(server.url + "/metrics").text:
                assert time.monotonic() < deadline
                time.sleep(0.01)
            with pytest.raises(E.QueueFull) as caught:  # ... one waiting: the next is 503
                once.generate(case.points, seed=case.good_seed)
            assert caught.value.status == 503 and caught.value.retry_after >= 1
            assert caught.value.retryable and isinstance(caught.value, E.Unavailable)
            patient = Client(server.url, retry=RetryPolicy(attempts=10, backoff=0.01))
            waiting = pool.submit(patient.generate, case.points, seed=case.good_seed)
            time.sleep(0.2)
        finally:
            gated.gate.set()
        meshes = [f.result(timeout=60) for f in (running, queued, waiting)]
        patient.close()
    assert len({m.data for m in meshes}) == 1


def test_a_server_that_starts_late_is_reached(generator, toy_repository, case, caplog):
    port = free_port()
    caplog.set_level(logging.INFO, logger="spacemesh_client")
    late = BackgroundServer(server_settings(toy_repository, port=port, warmup=False), generator)
    starter = threading.Timer(0.5, late.start)
    starter.start()
    try:
        with Client(f"http://127.0.0.1:{port}",
                    retry=RetryPolicy(attempts=30, backoff=0.05, max_backoff=0.2)) as client:
            mesh = client.generate(case.points, seed=case.good_seed)
    finally:
        starter.join()
        late.stop()
    assert mesh.stats.closed
    assert any("ConnectionFailed" in line for line in retries_logged(caplog))


@pytest.mark.parametrize("scheme", ["http", "grpc"])
def test_nobody_listening_gives_up_after_the_attempts(caplog, scheme):
    caplog.set_level(logging.INFO, logger="spacemesh_client")
    with Client(f"{scheme}://127.0.0.1:{free_port()}",
                retry=RetryPolicy(attempts=3, backoff=0.01)) as client:
        with pytest.raises(E.ConnectionFailed):
            client.generate([[0.0, 0.0, 0.0]] * 20)
        with pytest.raises(E.ConnectionFailed):
            client.health()
    assert len(retries_logged(caplog)) == 2  # 3 attempts: 2 retries


def test_client_timeout_is_not_retried(start_server, generator, case):
    gated = GatedGenerator(generator)
    server = start_server(gated, warmup=False, drain_timeout_s=1)
    try:
        for url in (server.url, "grpc://" + server.grpc_target):
            with Client(url, timeout=0.3, retry=RetryPolicy(attempts=5)) as client:
                started = time.monotonic()
                with pytest.raises(E.ClientTimeout):
                    client.generate(case.points, seed=case.good_seed)
                assert time.monotonic() - started < 3
    finally:
        gated.gate.set()


def test_server_timeout_is_504(start_server, generator, case):
    gated = GatedGenerator(generator)
    server = start_server(gated, warmup=False, request_timeout_s=0.3, drain_timeout_s=1,
                          **ADMIT_ALL)
    try:
        for url in (server.url, "grpc://" + server.grpc_target):
            with Client(url, retry=RetryPolicy(attempts=3)) as client:
                with pytest.raises(E.Timeout) as caught:
                    client.generate(case.points, seed=case.good_seed)
                assert caught.value.status == 504 and not caught.value.retryable
    finally:
        gated.gate.set()


# ---------------------------------------------------------------------- 429 (a proxy's)
def proxy_then_server(rest_url: str, answers: list[httpx.Response]) -> httpx.MockTransport:
    """A transport that answers ``answers`` first, then forwards to the real server."""
    forward = httpx.HTTPTransport()
    seen: list[float] = []

    def handle(request: httpx.Request) -> httpx.Response:
        seen.append(time.monotonic())
        if answers:
            return answers.pop(0)
        url = httpx.URL(rest_url).copy_with(path=request.url.path, query=request.url.query)
        real = httpx.Request(request.method, url, headers=request.headers,
                             content=request.read())
        response = forward.handle_request(real)
        response.read()
        return response

    transport = httpx.MockTransport(handle)
    transport.seen = seen  # type: ignore[attr-defined]
    return transport


def test_429_and_503_from_a_proxy_honour_retry_after(rest_url, case):
    answers = [httpx.Response(429, headers={"Retry-After": "0.4"}, text="slow down"),
               httpx.Response(503, headers={"Retry-After": "0.3"}, text="<html>busy</html>")]
    transport = proxy_then_server(rest_url, answers)
    with Client(rest_url, transport=transport, retry=RetryPolicy(backoff=0.001)) as client:
        mesh = client.generate(case.points, seed=case.good_seed)
    assert mesh.stats.closed
    seen = transport.seen
    assert len(seen) == 3 and seen[1] - seen[0] >= 0.4 and seen[2] - seen[1] >= 0.3


def test_a_long_retry_after_gives_up_at_once(rest_url, case):
    answers = [httpx.Response(429, headers={"Retry-After": "3600"})]
    transport = proxy_then_server(rest_url, answers)
    with Client(rest_url, transport=transport) as client, pytest.raises(E.RateLimited) as caught:
        client.generate(case.points)
    assert caught.value.retry_after == 3600


def test_async_client_retries_too(rest_url, case):
    answers = [httpx.Response(503, headers={"Retry-After": "0.2"})]
    seen: list[float] = []

    async def handle(request: httpx.Request) -> httpx.Response:
        seen.append(time.monotonic())
        if answers:
            return answers.pop(0)
        async with httpx.AsyncClient(base_url=rest_url) as real:
            return await real.send(httpx.Request(request.method, rest_url + request.url.path,
                                                 params=request.url.params,
                                                 headers=request.headers,
                                                 content=request.content))

    async def run():
        async with AsyncClient(rest_url, transport=httpx.MockTransport(handle)) as client:
            return await client.generate(case.points, seed=case.good_seed)

    assert asyncio.run(run()).stats.closed
    assert len(seen) == 2 and seen[1] - seen[0] >= 0.2


# ---------------------------------------------------------------------- the policy
def test_backoff_grows_to_its_cap_and_respects_retry_after():
    policy = RetryPolicy(attempts=10, backoff=0.5, max_backoff=3, jitter=False)
    busy = E.QueueFull("busy")
    assert [policy.delay(n, busy) for n in range(1, 6)] == [0.5, 1, 2, 3, 3]
    assert policy.delay(10, busy) is None  # the last attempt
    assert policy.delay(1, E.QueueFull("busy", retry_after=5)) == 5
    assert policy.delay(1, E.QueueFull("busy", retry_after=61)) is None
    assert policy.delay(1, E.InvalidParameter("no")) is None  # never retried
    assert policy.delay(1, E.ClientTimeout("slow")) is None
    jittered = RetryPolicy(backoff=1, max_backoff=1)
    assert all(0 <= jittered.delay(3, busy) <= 1 for _ in range(50))
    with pytest.raises(ValueError):
        RetryPolicy(attempts=0)


def test_retry_after_parsing():
    assert parse_retry_after("3") == 3.0 and parse_retry_after(" 0.5 ") == 0.5
    assert parse_retry_after(None) is None and parse_retry_after("soon") is None
    assert parse_retry_after("-4") == 0.0
    date = "Wed, 21 Oct 2015 07:28:00 GMT"
    now = 1445412480.0 - 30  # 30 s before that date
    assert parse_retry_after(date, now=now) == pytest.approx(30)
