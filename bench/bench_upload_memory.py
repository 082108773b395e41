"""Memory of uploads: each reader's peak at the default limits, and the real server's peak
RSS under concurrent bomb uploads, against the bound of docs/SERVICE.md ("Memory bound").

Usage::

    .venv/bin/python bench/bench_upload_memory.py [--clients 8] [--rounds 3] [--json OUT]

1. **Per-parse peak.** For every reader, the largest file the default limits let through
   (``max_points`` rows, or ``max_upload_bytes`` of mesh) is read in a fresh Python
   process with the server's limits (:func:`spacemesh_service.inputs.read_limits`); the
   peak is its ``VmHWM`` minus its ``VmRSS`` just before the read.
2. **The bound**: ``base + max_parallel_parses * max(per-parse peak) + clients * 2 *
   max_upload_bytes`` (every client's body, as received and as read from the form).
3. **The real server** (``spacemesh serve``, default settings, shipped model) gets
   ``--clients`` concurrent uploads, ``--rounds`` times: an ``.npz`` that inflates to 60 M
   points (1.4 MB), a 32 MB XYZ, a 32 MB JSON body, a PLY that declares 10^9 vertices, a
   GLB that declares 10^9 vertices, and an upload at the points limit; every bomb must get
   413 (the one at the limit 200 or 422). Its peak RSS is its ``VmHWM``.

Prints Markdown tables (Linux: reads ``/proc/PID/status``).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.io.bombs import glb_bomb, inflating_npz, ply_bomb  # noqa: E402

MB = 2**20


def status_kb(pid: int | str, field: str) -> int:
    """A ``/proc/PID/status`` field in kB (``VmHWM``, ``VmRSS``)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise KeyError(field)


# ---------------------------------------------------------------------- 1. per-parse peak
_READ_ONE = """
import sys, time
from pathlib import Path
from spacemesh_service.inputs import read_limits, read_upload, read_mesh_upload, read_json
from spacemesh_service.settings import Settings
from spacemesh_service.problems import Problem

def kb(field):
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith(field + ':'):
            return int(line.split()[1])

path, name, how = sys.argv[1:4]
data = Path(path).read_bytes()
limits = read_limits(Settings())
before = kb('VmRSS')
t0 = time.perf_counter()
try:
    if how == 'json':
        read_json(data, limits)
    elif how == 'mesh':
        read_mesh_upload(data, name, limits)
    else:
        read_upload(data, name, limits)
    outcome = 'read'
except Problem as problem:
    outcome = problem.kind.slug
print(kb('VmHWM') - before, time.perf_counter() - t0, outcome)
"""


def _cloud(rows: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.standard_normal((rows, 3)) * 1234.5678


def worst_files(max_points: int, max_bytes: int) -> dict[str, tuple[str, str, bytes]]:
    """Per reader: (file name, how it is read, the largest content the limits pass)."""
    from spacemesh.io import export_mesh
    from spacemesh.mesh import PolygonMesh

    points = _cloud(max_points)
    text = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in points.tolist()).encode()
    npz = io.BytesIO()
    np.savez(npz, points=points, normals=points)
    npy = io.BytesIO()
    np.save(npy, np.hstack([points, points]))
    body = json.dumps({"points": points.tolist(), "normals": points.tolist()}).encode()
    files = {
        "xyz (max_points rows)": ("cloud.xyz", "points", text[:max_bytes]),
        "json (points + normals)": ("body.json", "json", body[:max_bytes]),
        "npz (points + normals)": ("cloud.npz", "points", npz.getvalue()),
        "npy (N, 6)": ("cloud.npy", "points", npy.getvalue()),
        "ply ascii (max_points)": ("cloud.ply", "points",
                                   export_mesh(PolygonMesh.from_faces(points, np.zeros((0, 3),
                                               dtype=np.int64)), "ply", encoding="ascii")),
    }
    # meshes for /repair: as many triangles as fit in max_upload_bytes
    n = 200_000
    grid = np.stack(np.meshgrid(np.arange(n // 400 + 1), np.arange(401), indexing="ij"), -1)
    vertices = np.concatenate([grid.reshape(-1, 2) * 0.25, np.zeros((grid.size // 2, 1))], 1)
    for fmt, per_face in (("off", 22), ("obj", 24), ("ply", 13), ("stl", 50), ("glb", 12)):
        faces = max_bytes // per_face
        tri = np.stack([np.arange(faces) % (len(vertices) - 2),
                        np.arange(faces) % (len(vertices) - 2) + 1,
                        np.arange(faces) % (len(vertices) - 2) + 2], 1)
        mesh = PolygonMesh.from_faces(vertices, tri)
        data = export_mesh(mesh, fmt)
        while len(data) > max_bytes:
            tri = tri[: int(len(tri) * 0.95)]
            data = export_mesh(PolygonMesh.from_faces(vertices, tri), fmt)
        files[f"{fmt} mesh ({len(tri)} faces)"] = (f"mesh.{fmt}", "mesh", data)
    return files


def per_parse_peaks(max_points: int, max_bytes: int) -> dict[str, tuple[int, float, str, int]]:
    """Reader -> (peak MB, seconds, outcome, file bytes), each in a fresh process."""
    out = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, (filename, how, data) in worst_files(max_points, max_bytes).items():
            path = Path(folder) / filename
            path.write_bytes(data)
            run = subprocess.run([sys.executable, "-c", _READ_ONE, str(path), filename, how],
                                 capture_output=True, text=True, check=True,
                                 env={**os.environ, "OMP_NUM_THREADS": "1"})
            kb, seconds, outcome = run.stdout.split()
            out[name] = (int(kb) // 1024, float(seconds), outcome, len(data))
    return out


# ---------------------------------------------------------------------- 3. the server
def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def start_server(port: int, grpc_port: int) -> subprocess.Popen:
    import httpx

    command = [sys.executable, "-m", "spacemesh.cli", "serve", "--port", str(port),
               "--grpc-port", str(grpc_port), "--log-level", "warning", "--no-access-log"]
    process = subprocess.Popen(command, env={**os.environ, "OMP_NUM_THREADS": "1"})
    deadline = time.time() + 180
    while time.time() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/v2/health/ready", timeout=2).status_code == 200:
                return process
        except httpx.HTTPError:
            pass
        time.sleep(0.5)
    process.kill()
    raise RuntimeError("the server did not become ready")


def bombs(max_points: int, max_bytes: int) -> dict[str, dict]:
    """Name -> httpx request keywords of each upload."""
    xyz = (b"0.123456 1.234567 2.345678\n" * (max_bytes // 27 + 1))[: max_bytes - 1024]
    json_body = b'{"points": [' + b",".join(
        [b"[0.12345,1.23456,2.34567]"] * (max_bytes // 26)) + b"]}"
    json_body = json_body[: max_bytes - 1024].rsplit(b",", 1)[0] + b"]}"
    limit = _cloud(max_points)
    limit_xyz = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in limit.tolist()).encode()
    return {
        "npz bomb (60 M points, 1.4 MB)": {"files": {"file": ("bomb.npz",
                                                              inflating_npz(60_000_000))}},
        "xyz 32 MB": {"files": {"file": ("huge.xyz", xyz)}},
        "json 32 MB": {"content": json_body, "headers": {"content-type": "application/json"}},
        "ply lie (10^9 vertices)": {"files": {"file": ("lie.ply", ply_bomb())}},
        "glb lie (10^9 vertices)": {"files": {"file": ("lie.glb", glb_bomb())}},
        "xyz at max_points": {"files": {"file": ("limit.xyz", limit_xyz)},
                              "params": {"steps": 1}},
    }


def attack(url: str, requests: dict[str, dict], clients: int, rounds: int
           ) -> dict[str, tuple[dict[int, int], float]]:
    """Name -> (status counts, seconds) of ``clients`` concurrent uploads, ``rounds`` times."""
    import httpx

    results = {}
    with httpx.Client(base_url=url, timeout=300) as client:
        for name, keywords in requests.items():
            statuses: dict[int, int] = {}
            t0 = time.perf_counter()
            with ThreadPoolExecutor(clients) as pool:
                for _ in range(rounds):
                    sent = pool.map(lambda _, kw=keywords: client.post("/generate", **kw),
                                    range(clients))
                    for response in sent:
                        statuses[response.status_code] = statuses.get(response.status_code,
                                                                      0) + 1
            results[name] = (statuses, time.perf_counter() - t0)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()

    from spacemesh_service.settings import Settings

    settings = Settings()
    max_points, max_bytes = settings.max_points, settings.max_upload_bytes
    slots = settings.max_parallel_parses

    print(f"## Per-parse peak at the default limits (max_points {max_points}, "
          f"max_upload_bytes {max_bytes // MB} MB, mesh {settings.max_mesh_vertices} "
          f"vertices / {settings.max_mesh_faces} faces)\n")
    print("| upload | file MB | peak MB | seconds | outcome |\n|---|---:|---:|---:|---|")
    peaks = per_parse_peaks(max_points, max_bytes)
    for name, (peak, seconds, outcome, size) in peaks.items():
        print(f"| {name} | {size / MB:.1f} | {peak} | {seconds:.2f} | {outcome} |")
    worst = max(peak for peak, *_ in peaks.values())

    port, grpc_port = free_port(), free_port()
    server = start_server(port, grpc_port)
    try:
        base = status_kb(server.pid, "VmRSS") // 1024
        bound = base + slots * worst + args.clients * 2 * max_bytes // MB
        print(f"\n## The server under {args.clients} concurrent uploads x {args.rounds} "
              f"rounds (max_parallel_parses {slots})\n")
        print(f"Base RSS after warm-up: {base} MB. Bound: {base} + {slots} x {worst} + "
              f"{args.clients} x 2 x {max_bytes // MB} = {bound} MB.\n")
        print("| upload | statuses | seconds | server peak RSS MB so far |\n|---|---|---:|---:|")
        results = {}
        for name, keywords in bombs(max_points, max_bytes).items():
            (statuses, seconds), = attack(f"http://127.0.0.1:{port}", {name: keywords},
                                          args.clients, args.rounds).values()
            hwm = status_kb(server.pid, "VmHWM") // 1024
            results[name] = {"statuses": statuses, "seconds": seconds, "peak_rss_mb": hwm}
            shown = ", ".join(f"{k}: {v}" for k, v in sorted(statuses.items()))
            print(f"| {name} | {shown} | {seconds:.1f} | {hwm} |")
        peak = status_kb(server.pid, "VmHWM") // 1024
        print(f"\nServer peak RSS: {peak} MB; documented bound {bound} MB "
              f"({'within' if peak <= bound else 'OVER'}).")
        if args.json:
            args.json.write_text(json.dumps({
                "per_parse_peak_mb": {k: v[0] for k, v in peaks.items()}, "base_mb": base,
                "bound_mb": bound, "peak_rss_mb": peak, "uploads": results}, indent=2))
    finally:
        server.terminate()
        server.wait(60)


if __name__ == "__main__":
    main()
