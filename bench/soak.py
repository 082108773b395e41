"""Load and soak: N clients for M minutes of mixed valid and invalid requests.

Usage::

    .venv/bin/python bench/soak.py [--clients 4] [--minutes 1] [--url http://HOST:PORT
        --grpc HOST:PORT [--pid PID]] [--model DIR] [--seed 0] [--heavy] [--json OUT]

Without ``--url`` it starts the real server itself (``spacemesh serve``, default settings,
the shipped model unless ``--model``; its output goes to a log file) and reads the
server's peak RSS (``VmHWM`` of ``/proc/PID/status``) at the end; with ``--url`` it soaks
a running server (``--pid`` for its peak RSS, when it runs on this machine).

Each client loops until the time is up over a fixed mix, drawn with its own seed:

- valid: generate over REST (a PLY upload, a JSON body), gRPC ``Generate`` and
  ``GenerateStream``, repair over REST and gRPC;
- invalid: a file that is not a point cloud, a truncated PLY, a bad option, a bad
  format, a seed that is not an integer (``1e3``), an unknown option, too few points,
  NaN, a deeply nested JSON body, an ``.npz`` that inflates to 60 M points, a bad repair
  region, an empty gRPC request, a bad gRPC option.

With ``--heavy`` the mix also holds heavy valid requests (bench/heavy_requests.py):
``target_vertices=2048&samples=4`` on 200,000 points of a real mesh (admitted by the
default budget), ``{"auto": "all"}`` on a 324,216-face mesh with 6 holes (admitted), and
requests the budget refuses before any work (``target_vertices=10000`` on the example
cloud, the same repair with 20 holes: 422 ``too-expensive``). A heavy admitted request
deserves a 200, or, when the heavy ones queue behind each other past the deadline, an
honest 504 ``timeout`` or 503 ``queue-full``: those are counted apart (``overload``),
never a 500.

Every answer is checked against what the request deserves (200, or the problem kind it
must get). It prints the latency percentiles (p50, p95, p99) of the valid and the
invalid requests (and of the small valid ones, without the heavy), the answers by status
and by problem kind, the number of 5xx answers (gRPC INTERNAL, UNKNOWN, UNAVAILABLE,
DATA_LOSS count as 5xx; there must be none but the heavy requests' honest overload
answers), the 500s, the answers that were not the expected ones, and the server's peak
RSS. Exit status 1 if any 500, other 5xx or unexpected answer was seen.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_upload_memory import free_port, status_kb  # noqa: E402

from tests.io.bombs import inflating_npz  # noqa: E402

PROBLEM = "https://spacemesh.dev/problems/"
#: gRPC codes that are server errors (the 5xx of gRPC).
GRPC_SERVER_ERRORS = {"INTERNAL", "UNKNOWN", "UNAVAILABLE", "DATA_LOSS"}
#: The honest answers of an admitted heavy request that waited behind others.
OVERLOAD = {("504", "timeout"), ("503", "queue-full")}


@dataclass(frozen=True)
class Outcome:
    """One answer: which request, how long it took, what came back."""

    name: str
    valid: bool
    seconds: float
    status: str  # "200", "422", ... or a gRPC code name
    kind: str  # the problem's slug ("" on success)
    server_error: bool
    expected: bool
    heavy: bool = False
    overload: bool = False  # a heavy admitted request's honest 504 timeout or 503 queue-full


# ---------------------------------------------------------------------- inputs
def cloud(count: int = 2048, seed: int = 0) -> np.ndarray:
    """Points on an ellipsoid (float32-exact)."""
    d = np.random.default_rng(seed).standard_normal((count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return (d * np.array([1.5, 1.0, 0.75])).astype(np.float32).astype(np.float64)


def ply(points: np.ndarray) -> bytes:
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n").encode()
    return header + points.astype("<f4").tobytes()


@dataclass(frozen=True)
class Heavy:
    """The heavy inputs (``--heavy``)."""

    cloud: bytes  # 200,000 points of a real mesh, binary PLY
    big_mesh: bytes  # 324,216 faces, 6 holes, binary PLY
    bigger_mesh: bytes  # 315,982 faces, 20 holes: too expensive
    example: bytes  # examples/points.ply

    @classmethod
    def make(cls) -> Heavy:
        from bench.heavy_requests import binary_ply, holed_icosphere, real_cloud
        from spacemesh.io import export_mesh

        return cls(binary_ply(real_cloud()), export_mesh(holed_icosphere(7, 6), "ply"),
                   export_mesh(holed_icosphere(7, 20), "ply"),
                   (ROOT / "examples" / "points.ply").read_bytes())


@dataclass(frozen=True)
class Inputs:
    points: np.ndarray
    ply: bytes
    mesh: bytes  # an OBJ to repair
    region: dict
    bomb: bytes
    heavy: Heavy | None = None

    @classmethod
    def make(cls, heavy: bool = False) -> Inputs:
        from spacemesh.examples import icosphere
        from spacemesh.io import export_mesh

        points = cloud()
        sphere = icosphere(2)
        star = [int(f) for f in np.unique(sphere.face_of_corner[sphere.face_indices == 0])]
        return cls(points, ply(points), export_mesh(sphere, "obj"), {"faces": star},
                   inflating_npz(60_000_000), Heavy.make() if heavy else None)


# ---------------------------------------------------------------------- requests
class Soak:
    """The request mix against one server (thread-safe: one httpx client, one channel)."""

    def __init__(self, url: str, grpc_target: str, inputs: Inputs) -> None:
        import grpc
        import httpx

        from spacemesh_service.pb import spacemesh_pb2 as pb
        from spacemesh_service.pb import spacemesh_pb2_grpc as pb_grpc

        self.pb, self.grpc, self.inputs = pb, grpc, inputs
        self.http = httpx.Client(base_url=url, timeout=300)
        self.channel = grpc.insecure_channel(grpc_target, options=[
            ("grpc.max_send_message_length", 64 << 20),
            ("grpc.max_receive_message_length", 64 << 20)])
        self.stub = pb_grpc.SpaceMeshStub(self.channel)
        p = inputs.points
        points_pb = pb.Points(xyz=p.ravel().tolist())
        few = pb.Points(xyz=p[:5].ravel().tolist())
        nested = b'{"points": ' + b"[" * 20_000 + b"]" * 20_000 + b"}"  # nesting, not size
        truncated = inputs.ply[: len(inputs.ply) // 2]
        repair_pb = pb.RepairRequest(mesh=inputs.mesh, filename="mesh.obj",
                                     faces=inputs.region["faces"], format="obj")
        region = json.dumps(inputs.region)
        # name -> (valid, the problem kind it must get or "", weight, call); the npz bomb
        # inflates past the upload limit before it reaches the points limit
        self.mix: dict[str, tuple[bool, str, int, Callable[[], tuple[str, str]]]] = {
            "rest generate ply": (True, "", 4, lambda: self.rest(
                "/generate", params={"format": "glb"},
                files={"file": ("cloud.ply", inputs.ply)})),
            "rest generate json": (True, "", 2, lambda: self.rest(
                "/generate", json={"points": p.tolist(), "format": "obj"})),
            "grpc generate": (True, "", 3, lambda: self.rpc(
                self.stub.Generate, pb.GenerateRequest(points=points_pb, format="ply"))),
            "grpc generate stream": (True, "", 1, lambda: self.rpc(
                lambda r: list(self.stub.GenerateStream(r)),
                pb.GenerateRequest(points=points_pb, format="glb"))),
            "rest repair": (True, "", 2, lambda: self.rest(
                "/repair", params={"format": "obj"},
                files={"file": ("mesh.obj", inputs.mesh)}, data={"region": region})),
            "grpc repair": (True, "", 1, lambda: self.rpc(self.stub.Repair, repair_pb)),
            "rest not a cloud": (False, "unsupported-format", 1, lambda: self.rest(
                "/generate", files={"file": ("notes.docx", bytes(range(256)) * 8)})),
            "rest truncated ply": (False, "malformed-input", 1, lambda: self.rest(
                "/generate", files={"file": ("cloud.ply", truncated)})),
            "rest bad option": (False, "invalid-option", 1, lambda: self.rest(
                "/generate", params={"steps": 0}, files={"file": ("cloud.ply", inputs.ply)})),
            "rest bad format": (False, "invalid-option", 1, lambda: self.rest(
                "/generate", params={"format": "docx"},
                files={"file": ("cloud.ply", inputs.ply)})),
            "rest float seed": (False, "invalid-option", 1, lambda: self.rest(
                "/generate", params={"seed": "1e3"},
                files={"file": ("cloud.ply", inputs.ply)})),
            "rest unknown option": (False, "invalid-option", 1, lambda: self.rest(
                "/generate", json={"points": p.tolist(), "colour": "red"})),
            "rest too few points": (False, "too-few-points", 1, lambda: self.rest(
                "/generate", json={"points": p[:5].tolist()})),
            "rest nan": (False, "non-finite", 1, lambda: self.rest(
                "/generate", files={"file": ("cloud.xyz", b"0 0 0\n1 nan 2\n" * 40)})),
            "rest nested json": (False, "malformed-input", 1, lambda: self.rest(
                "/generate", content=nested, headers={"content-type": "application/json"})),
            "rest npz bomb": (False, "payload-too-large", 1, lambda: self.rest(
                "/generate", files={"file": ("bomb.npz", inputs.bomb)})),
            "rest bad region": (False, "invalid-region", 1, lambda: self.rest(
                "/repair", files={"file": ("mesh.obj", inputs.mesh)},
                data={"region": '{"sphere": {"center": [0, 0, 0], "radius": -1}}'})),
            "grpc empty request": (False, "malformed-input", 1, lambda: self.rpc(
                self.stub.Generate, pb.GenerateRequest())),
            "grpc bad option": (False, "invalid-option", 1, lambda: self.rpc(
                self.stub.Generate, pb.GenerateRequest(points=points_pb, samples=99))),
            "grpc too few points": (False, "too-few-points", 1, lambda: self.rpc(
                self.stub.Generate, pb.GenerateRequest(points=few))),
        }
        if inputs.heavy is not None:
            self.mix.update(self.heavy_mix(inputs.heavy))

    def heavy_mix(self, heavy: Heavy) -> dict[str, tuple[bool, str, int,
                                                         Callable[[], tuple[str, str]]]]:
        """The heavy requests: admitted ones (the problem kind "heavy") and ones the
        budget refuses (``too-expensive``)."""
        from bench.heavy_requests import AUTO_ALL, HEAVY_GENERATE

        auto = json.dumps(AUTO_ALL)
        return {
            "rest heavy generate": (True, "heavy", 1, lambda: self.rest(
                "/generate", params={**HEAVY_GENERATE, "seed": 0, "format": "ply"},
                files={"file": ("cloud.ply", heavy.cloud)})),
            "rest big repair": (True, "heavy", 1, lambda: self.rest(
                "/repair", params={"format": "ply"},
                files={"file": ("mesh.ply", heavy.big_mesh)}, data={"region": auto})),
            "rest too expensive generate": (False, "too-expensive", 1, lambda: self.rest(
                "/generate", params={"target_vertices": 10_000},
                files={"file": ("points.ply", heavy.example)})),
            "rest too expensive repair": (False, "too-expensive", 1, lambda: self.rest(
                "/repair", files={"file": ("mesh.ply", heavy.bigger_mesh)},
                data={"region": auto})),
        }

    def rest(self, route: str, **keywords) -> tuple[str, str]:
        response = self.http.post(route, **keywords)
        kind = ""
        if response.headers.get("content-type", "").startswith("application/problem+json"):
            kind = response.json().get("type", "").removeprefix(PROBLEM)
        return str(response.status_code), kind

    def rpc(self, call: Callable, request) -> tuple[str, str]:
        try:
            call(request)
        except self.grpc.RpcError as error:
            metadata = dict(error.trailing_metadata() or ())
            return error.code().name, metadata.get("problem-type", "").removeprefix(PROBLEM)
        return "OK", ""

    def one(self, name: str) -> Outcome:
        valid, expected_kind, _, call = self.mix[name]
        started = time.perf_counter()
        try:
            status, kind = call()
        except Exception as error:  # a dropped connection is a server error too
            status, kind = f"{type(error).__name__}", "transport-error"
        seconds = time.perf_counter() - started
        server_error = (status.isdigit() and int(status) >= 500) or (
            status in GRPC_SERVER_ERRORS) or kind == "transport-error"
        ok = status in ("200", "OK")
        expected = ok if valid else (not ok and kind == expected_kind)
        if valid and not ok and kind == "no-surface":  # an honest answer for some seeds
            expected = True
        heavy = expected_kind == "heavy" or name.startswith("rest too expensive")
        overload = expected_kind == "heavy" and (status, kind) in OVERLOAD
        if overload:  # admitted, but queued behind the other heavy ones past the deadline
            expected, server_error = True, False
        return Outcome(name, valid, seconds, status, kind, server_error, expected, heavy,
                       overload)

    def client(self, index: int, seed: int, until: float, out: list[Outcome],
               lock: threading.Lock) -> None:
        rng = np.random.default_rng([seed, index])
        names = list(self.mix)
        weights = np.array([self.mix[n][2] for n in names], dtype=np.float64)
        weights /= weights.sum()
        while time.monotonic() < until:
            outcome = self.one(names[rng.choice(len(names), p=weights)])
            with lock:
                out.append(outcome)

    def close(self) -> None:
        self.http.close()
        self.channel.close()


# ---------------------------------------------------------------------- the server
def start_server(model: Path | None, log: io.TextIOBase) -> tuple[object, str, str]:
    """``spacemesh serve`` on free ports (default settings); (process, url, grpc target)."""
    import subprocess

    import httpx

    port, grpc_port = free_port(), free_port()
    command = [sys.executable, "-m", "spacemesh.cli", "serve", "--port", str(port),
               "--grpc-port", str(grpc_port)]
    if model is not None:
        command += ["--model", str(model)]
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT,
                               env={**os.environ, "OMP_NUM_THREADS": "1"})
    url = f"http://127.0.0.1:{port}"
    deadline = time.time() + 300
    while time.time() < deadline and process.poll() is None:
        try:
            if httpx.get(url + "/v2/health/ready", timeout=2).status_code == 200:
                return process, url, f"127.0.0.1:{grpc_port}"
        except httpx.HTTPError:
            pass
        time.sleep(0.5)
    process.kill()
    raise RuntimeError("the server did not become ready (see its log)")


# ---------------------------------------------------------------------- report
def percentiles(values: list[float]) -> tuple[float, float, float]:
    if not values:
        return (float("nan"),) * 3
    p50, p95, p99 = np.percentile(np.asarray(values) * 1000, [50, 95, 99])
    return float(p50), float(p95), float(p99)


def report(outcomes: list[Outcome], seconds: float, clients: int,
           peak_rss_mb: float | None) -> dict:
    valid = [o for o in outcomes if o.valid]
    invalid = [o for o in outcomes if not o.valid]
    small = [o for o in valid if not o.heavy]
    groups = (("all", outcomes), ("valid", valid), ("small valid", small),
              ("invalid", invalid))
    summary = {
        "clients": clients, "seconds": round(seconds, 1), "requests": len(outcomes),
        "requests_per_s": round(len(outcomes) / max(seconds, 1e-9), 2),
        "latency_ms": {name: dict(zip(("p50", "p95", "p99"), map(lambda v: round(v, 1),
                                                                   percentiles(
                       [o.seconds for o in group])), strict=True))
                       for name, group in groups},
        "answers": dict(sorted(Counter(o.kind or "ok" for o in outcomes).items())),
        "statuses": dict(sorted(Counter(o.status for o in outcomes).items())),
        "server_errors": sum(o.server_error for o in outcomes),
        "internal_errors": sum(o.status in ("500", "INTERNAL") for o in outcomes),
        "overload": sum(o.overload for o in outcomes),
        "unexpected": [f"{o.name}: {o.status} {o.kind}" for o in outcomes if not o.expected],
        "peak_rss_mb": peak_rss_mb,
        "by_request": {name: {"count": len(g), "p50_ms": round(percentiles(
            [o.seconds for o in g])[0], 1)} for name in sorted({o.name for o in outcomes})
            for g in [[o for o in outcomes if o.name == name]]},
    }
    print(f"\n## Soak: {clients} clients, {seconds:.0f} s, {len(outcomes)} requests "
          f"({summary['requests_per_s']} / s)\n")
    print("| requests | count | p50 ms | p95 ms | p99 ms |\n|---|---:|---:|---:|---:|")
    for name, group in groups:
        p50, p95, p99 = percentiles([o.seconds for o in group])
        print(f"| {name} | {len(group)} | {p50:.0f} | {p95:.0f} | {p99:.0f} |")
    heavy = sorted({o.name for o in outcomes if o.heavy})
    if heavy:
        print("\n| heavy request | count | answers | p50 s | max s |\n|---|---:|---|---:|---:|")
        for name in heavy:
            mine = [o for o in outcomes if o.name == name]
            answers = ", ".join(f"{k} x{c}" for k, c in sorted(Counter(
                f"{o.status} {o.kind}".strip() for o in mine).items()))
            times = [o.seconds for o in mine]
            print(f"| {name} | {len(mine)} | {answers} | {np.median(times):.1f} | "
                  f"{max(times):.1f} |")
    print("\n| status | count |\n|---|---:|")
    for status, count in summary["statuses"].items():
        print(f"| {status} | {count} |")
    print("\n| answer (problem kind) | count |\n|---|---:|")
    for kind, count in summary["answers"].items():
        print(f"| {kind} | {count} |")
    print(f"\n500 answers: {summary['internal_errors']}")
    print(f"heavy requests answered 504 timeout or 503 queue-full: {summary['overload']}")
    print(f"other 5xx answers: {summary['server_errors']}")
    print(f"unexpected answers: {len(summary['unexpected'])}")
    for line in sorted(set(summary["unexpected"]))[:20]:
        print(f"  {line}")
    print("server peak RSS: " + (f"{peak_rss_mb:.0f} MB" if peak_rss_mb is not None
                                 else "unknown (pass --pid)"))
    return summary


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=4)
    parser.add_argument("--minutes", type=float, default=1.0)
    parser.add_argument("--url", default=None, help="REST URL of a running server")
    parser.add_argument("--grpc", default=None, help="its gRPC host:port (with --url)")
    parser.add_argument("--pid", type=int, default=None, help="its process id (peak RSS)")
    parser.add_argument("--model", type=Path, default=None, help="model to serve")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="also write the figures")
    parser.add_argument("--heavy", action="store_true",
                        help="mix in heavy valid requests and too-expensive ones")
    args = parser.parse_args()
    if args.url and not args.grpc:
        parser.error("--url needs --grpc HOST:PORT")

    inputs = Inputs.make(args.heavy)
    process, log = None, None
    if args.url:
        url, target, pid = args.url.rstrip("/"), args.grpc, args.pid
    else:
        log = tempfile.NamedTemporaryFile("w+", prefix="soak-server-", suffix=".log",
                                          delete=False)
        process, url, target = start_server(args.model, log)
        pid = process.pid
        print(f"server: {url}, grpc {target}, pid {pid}, log {log.name}")
    soak = Soak(url, target, inputs)
    outcomes: list[Outcome] = []
    lock = threading.Lock()
    started = time.monotonic()
    until = started + 60.0 * args.minutes
    threads = [threading.Thread(target=soak.client, args=(i, args.seed, until, outcomes, lock))
               for i in range(args.clients)]
    try:
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        seconds = time.monotonic() - started
        peak = status_kb(pid, "VmHWM") / 1024 if pid is not None else None
    finally:
        soak.close()
        if process is not None:
            process.terminate()
            process.wait(60)
    summary = report(outcomes, seconds, args.clients, peak)
    if args.json:
        args.json.write_text(json.dumps(summary, indent=2))
    return 1 if (summary["server_errors"] or summary["internal_errors"]
                 or summary["unexpected"]) else 0


if __name__ == "__main__":
    sys.exit(main())
