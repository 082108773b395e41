"""Issue 37's bar, clause by clause, on a real server: prints one table row per check.

Starts ``spacemesh serve`` with its default settings (the shipped model, a 30 s deadline,
the default budget) on free ports, and measures:

1. **The reproductions** each get a 422 before any work or finish within their deadline:
   ``samples=16&target_vertices=10000&steps=1024&start=points&start_time=1`` on 200,000
   points, ``target_vertices=10000`` on examples/points.ply, ``{"auto": "all"}`` on a
   324,216-face mesh with 6 holes, and the request the default budget admits
   (``target_vertices=2048&samples=4`` on 200,000 points of a real mesh;
   bench/heavy_requests.py). A 422 counts as "before any work" when the server ran no
   batch for it (``spacemesh_batches_total`` and the lanes' stopped calls unchanged).
2. **The CPU falls idle within 2 s** (under 0.1 s of CPU in a 0.5 s window,
   bench_abandoned_work.py) after each of those answers, after a REST client that leaves
   5 s into the admitted heavy request (8 s into the repair), and after a gRPC
   ``Generate`` of it cancelled 5 s in; and after requests past their deadline (a second
   server with a budget that admits everything and a 10 s deadline: the issue's first
   reproduction and the repair, 504).
3. **A small generate gets a 200 within 10 s** while the admitted heavy one runs
   (bench_lanes.py's small request; the heavy one is seen running in the metrics).
4. **Four concurrent ``target_vertices=10000``** requests keep the server's peak RSS
   (``VmHWM``, over everything it has done so far) under 2 GB.
5. **``seed=1e3`` never gives a 500** (REST query, form, JSON body and the stream; a 422
   ``invalid-option`` or a 200 are both fine) and **an unknown query option is refused**.
6. **A request sent just after SIGTERM gets a 503** (``shutting-down``).

Every row prints what was measured and whether the clause holds. Linux only (``/proc``).

Usage::

    python bench/bench_serving_bar.py [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import re
import signal
import socket
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_abandoned_work import HEAVY as FIRST_REPRODUCTION  # noqa: E402
from bench_abandoned_work import seconds_to_idle  # noqa: E402
from bench_lanes import running  # noqa: E402
from bench_lanes import small as small_generate  # noqa: E402
from bench_upload_memory import free_port, status_kb  # noqa: E402

from bench.heavy_requests import (  # noqa: E402
    AUTO_ALL,
    HEAVY_GENERATE,
    binary_ply,
    holed_icosphere,
    real_cloud,
)

EXAMPLE = ROOT / "examples" / "points.ply"
PROBLEM = "https://spacemesh.dev/problems/"
DEADLINE_S = 30.0
#: How soon the CPU must fall idle (s), how soon a small generate must answer (s).
IDLE_S, SMALL_S = 2.0, 10.0
PEAK_MB = 2048.0


class Server:
    """``spacemesh serve`` in a subprocess on free ports."""

    def __init__(self, *extra: str) -> None:
        import subprocess

        import httpx

        self.port, self.grpc_port = free_port(), free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "spacemesh.cli", "serve", "--port", str(self.port),
             "--grpc-port", str(self.grpc_port), "--host", "127.0.0.1", "--log-level",
             "warning", "--no-access-log", *extra])
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and self.process.poll() is None:
            try:
                if httpx.get(self.url + "/v2/health/ready", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.3)
        self.process.kill()
        raise SystemExit("the server did not become ready")

    @property
    def pid(self) -> int:
        return self.process.pid

    def metric(self, name: str) -> float:
        """The sum of a metric's samples (every label)."""
        import httpx

        text = httpx.get(self.url + "/metrics", timeout=10).text
        return sum(float(v) for v in re.findall(rf"^{re.escape(name)}(?:{{[^}}]*}})? (\S+)$",
                                                text, re.M))

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait(60)


class Bar:
    """The table of checks."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = []

    def add(self, clause: str, check: str, measured: str, holds: bool) -> None:
        self.rows.append({"clause": clause, "check": check, "measured": measured,
                          "holds": bool(holds)})
        print(f"| {clause} | {check} | {measured} | {'yes' if holds else '**no**'} |",
              flush=True)


def post(url: str, route: str, query: dict | str, timeout: float = 300.0,
         **keywords: Any) -> tuple[int, str, float]:
    """POST and time it: (status, problem kind or "", seconds)."""
    import httpx

    started = time.monotonic()
    target = f"{url}{route}?{query}" if isinstance(query, str) else f"{url}{route}"
    params = None if isinstance(query, str) else query
    reply = httpx.post(target, params=params, timeout=timeout, **keywords)
    seconds = time.monotonic() - started
    kind = ""
    if reply.headers.get("content-type", "").startswith("application/problem+json"):
        kind = reply.json().get("type", "").removeprefix(PROBLEM)
    return reply.status_code, kind, seconds


def reproductions(server: Server, bar: Bar, inputs: dict[str, bytes]) -> None:
    """Clauses 1 and 2 (after each answer)."""
    cases = [
        ("first reproduction, 200,000 points", "/generate", FIRST_REPRODUCTION,
         {"files": {"file": ("cloud.ply", inputs["cloud"])}}),
        ("second reproduction, examples/points.ply", "/generate", "target_vertices=10000",
         {"files": {"file": ("points.ply", inputs["example"])}}),
        ("repair, 324,216 faces, auto=all", "/repair", "format=ply",
         {"files": {"file": ("mesh.ply", inputs["mesh"])},
          "data": {"region": json.dumps(AUTO_ALL)}}),
        ("admitted heavy generate, 200,000 real points", "/generate",
         "&".join(f"{k}={v}" for k, v in HEAVY_GENERATE.items()) + "&seed=0&format=ply",
         {"files": {"file": ("cloud.ply", inputs["cloud"])}}),
    ]
    for name, route, query, keywords in cases:
        batches = server.metric("spacemesh_batches_total")
        calls = server.metric("spacemesh_stopped_batches_total")
        status, kind, seconds = post(server.url, route, query, **keywords)
        idle = seconds_to_idle(server.pid)
        ran = (server.metric("spacemesh_batches_total") != batches
               or server.metric("spacemesh_stopped_batches_total") != calls)
        refused = status == 422 and kind == "too-expensive" and not (
            route == "/generate" and ran)
        within = status == 200 and seconds <= DEADLINE_S
        bar.add("1 reproductions", name,
                f"{status} {kind} after {seconds:.1f} s"
                + (" (no batch ran)" if status == 422 and not ran else ""),
                refused or within)
        bar.add("2 CPU idle", f"after the answer: {name}", f"idle {idle:.1f} s later",
                idle <= IDLE_S)


def heavy_query() -> str:
    return "&".join(f"{k}={v}" for k, v in HEAVY_GENERATE.items()) + "&seed=0"


def leave_after(port: int, target: str, parts: dict[str, tuple[str, bytes]],
                seconds: float = 5.0) -> None:
    """POST ``parts`` (name -> (filename or "", bytes)) as a multipart body written by
    hand, then close the connection ``seconds`` later without reading the answer."""
    boundary = "spacemesh-bar"
    body = b""
    for name, (filename, data) in parts.items():
        label = f'; filename="{filename}"' if filename else ""
        body += (f"--{boundary}\r\nContent-Disposition: form-data; name=\"{name}\"{label}"
                 "\r\n\r\n").encode() + data + b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    head = (f"POST {target} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: multipart/form-data; "
            f"boundary={boundary}\r\nContent-Length: {len(body)}\r\n\r\n").encode()
    with socket.create_connection(("127.0.0.1", port)) as client:
        client.sendall(head + body)
        time.sleep(seconds)


def disconnect_and_cancel(server: Server, bar: Bar, inputs: dict[str, bytes]) -> None:
    """Clause 2: a REST client that leaves (a generate, a repair), a gRPC call cancelled."""
    import grpc

    from spacemesh_service.pb import spacemesh_pb2 as pb
    from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

    cloud = inputs["cloud"]
    leave_after(server.port, f"/generate?{heavy_query()}", {"file": ("cloud.ply", cloud)})
    idle = seconds_to_idle(server.pid)
    bar.add("2 CPU idle", "REST client gone 5 s into the admitted heavy generate",
            f"idle {idle:.1f} s later", idle <= IDLE_S)
    leave_after(server.port, "/repair?format=ply", {
        "file": ("mesh.ply", inputs["mesh"]), "region": ("", json.dumps(AUTO_ALL).encode())},
        seconds=8.0)
    idle = seconds_to_idle(server.pid)
    bar.add("2 CPU idle", "REST client gone 8 s into the repair of 324,216 faces",
            f"idle {idle:.1f} s later", idle <= IDLE_S)

    with grpc.insecure_channel(f"127.0.0.1:{server.grpc_port}", options=[
            ("grpc.max_send_message_length", 64 << 20)]) as channel:
        stub = pb_grpc.SpaceMeshStub(channel)
        request = pb.GenerateRequest(file=pb.PointCloudFile(data=cloud, filename="cloud.ply"),
                                     format="ply", seed=0, **HEAVY_GENERATE)
        call = stub.Generate.future(request)
        time.sleep(5.0)
        call.cancel()
        idle = seconds_to_idle(server.pid)
    bar.add("2 CPU idle", "gRPC Generate of it cancelled 5 s in", f"idle {idle:.1f} s later",
            idle <= IDLE_S)


def past_deadline(bar: Bar, mesh: bytes) -> None:
    """Clause 2: requests past their deadline (a server that admits everything)."""
    server = Server("--request-timeout-s", "10", "--request-budget-s", "1000000",
                    "--request-budget-mb", "1000000")
    try:
        status, kind, seconds = post(server.url, "/generate", FIRST_REPRODUCTION,
                                     files={"file": ("points.ply", EXAMPLE.read_bytes())})
        idle = seconds_to_idle(server.pid)
        bar.add("2 CPU idle", "the first reproduction past a 10 s deadline (admit-all budget)",
                f"{status} {kind} after {seconds:.1f} s; idle {idle:.1f} s later",
                status == 504 and idle <= IDLE_S)
        status, kind, seconds = post(server.url, "/repair", "format=ply", files={
            "file": ("mesh.ply", mesh)}, data={"region": json.dumps(AUTO_ALL)})
        idle = seconds_to_idle(server.pid)
        bar.add("2 CPU idle", "the repair of 324,216 faces past a 10 s deadline",
                f"{status} {kind} after {seconds:.1f} s; idle {idle:.1f} s later",
                status == 504 and idle <= IDLE_S)
    finally:
        server.stop()


def small_while_heavy(server: Server, bar: Bar, cloud: bytes) -> None:
    """Clause 3."""
    import httpx

    heavy: dict[str, Any] = {}

    def send() -> None:
        status, kind, seconds = post(server.url, "/generate", heavy_query(),
                                     files={"file": ("cloud.ply", cloud)})
        heavy.update(status=status, kind=kind, seconds=seconds)

    thread = threading.Thread(target=send)
    thread.start()
    while not running(server.url, httpx) and thread.is_alive():
        time.sleep(0.05)
    status, seconds = small_generate(server.url, httpx)
    still = thread.is_alive()
    thread.join()
    bar.add("3 small request", "small generate while the admitted heavy one runs",
            f"{status} after {seconds:.1f} s (heavy {'still running' if still else 'done'}; "
            f"heavy: {heavy.get('status')} after {heavy.get('seconds', 0):.1f} s)",
            status == 200 and seconds <= SMALL_S and still)


def four_large(server: Server, bar: Bar, example: bytes) -> None:
    """Clause 4."""
    answers: list[tuple[int, str, float]] = []

    def send() -> None:
        answers.append(post(server.url, "/generate", "target_vertices=10000",
                            files={"file": ("points.ply", example)}))

    threads = [threading.Thread(target=send) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    peak = status_kb(server.pid, "VmHWM") / 1024
    kinds = ", ".join(sorted(f"{s} {k}" for s, k, _ in answers))
    bar.add("4 memory", "four concurrent target_vertices=10000",
            f"{kinds}; server peak RSS so far {peak:.0f} MB", peak < PEAK_MB)


def options(server: Server, bar: Bar, example: bytes) -> None:
    """Clause 5."""
    import httpx

    from spacemesh.io import load_points

    files = {"file": ("points.ply", example)}
    points = load_points(EXAMPLE)[0].tolist()
    sent = {"REST query": lambda: post(server.url, "/generate", "seed=1e3", files=files),
            "REST form": lambda: post(server.url, "/generate", {}, files=files,
                                      data={"seed": "1e3"}),
            "JSON body, a string": lambda: post(server.url, "/generate", {}, json={
                "points": points, "seed": "1e3"}),
            "JSON body, a number": lambda: post(server.url, "/generate", {}, json={
                "points": points, "seed": 1e3})}
    for name, call in sent.items():
        status, kind, _ = call()
        bar.add("5 options", f"seed=1e3 ({name})", f"{status} {kind}", status != 500)
    with httpx.stream("POST", f"{server.url}/generate/stream?seed=1e3", files=files,
                      timeout=60) as reply:
        text = reply.read().decode(errors="replace")
    bar.add("5 options", "seed=1e3 (the stream)",
            f"{reply.status_code} {text[:80]!r}", reply.status_code != 500
            and "internal-error" not in text)
    status, kind, _ = post(server.url, "/generate", "colour=red", files=files)
    bar.add("5 options", "an unknown query option (colour=red)", f"{status} {kind}",
            status == 422 and kind == "invalid-option")


def after_sigterm(server: Server, bar: Bar, example: bytes) -> None:
    """Clause 6."""
    server.process.send_signal(signal.SIGTERM)
    time.sleep(0.2)
    status, kind, _ = post(server.url, "/generate", "seed=0",
                           files={"file": ("points.ply", example)})
    bar.add("6 shutdown", "a generate 0.2 s after SIGTERM", f"{status} {kind}",
            status == 503 and kind == "shutting-down")
    server.process.wait(60)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    from spacemesh.io import export_mesh

    inputs = {"cloud": binary_ply(real_cloud()), "example": EXAMPLE.read_bytes(),
              "mesh": export_mesh(holed_icosphere(7, 6), "ply")}
    bar = Bar()
    print("| clause | check | measured | holds |\n|---|---|---|---|", flush=True)
    server = Server()
    try:
        reproductions(server, bar, inputs)
        disconnect_and_cancel(server, bar, inputs)
        small_while_heavy(server, bar, inputs["cloud"])
        four_large(server, bar, inputs["example"])
        options(server, bar, inputs["example"])
        after_sigterm(server, bar, inputs["example"])
    finally:
        server.stop()
    past_deadline(bar, inputs["mesh"])
    held = sum(row["holds"] for row in bar.rows)
    print(f"\n{held} of {len(bar.rows)} checks hold", flush=True)
    if args.json:
        args.json.write_text(json.dumps(bar.rows, indent=1))
    return 0 if held == len(bar.rows) else 1


if __name__ == "__main__":
    sys.exit(main())
