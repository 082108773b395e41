"""A big cloud over REST: wall time and the server's peak RSS (issue 36's bar).

Starts the real server (``spacemesh serve``, default settings, shipped model), samples
N points on a torus's surface (:func:`spacemesh.primitives.sample_surface`, float32 x y z,
no normals), writes them as a binary PLY, posts it to ``/generate`` with httpx and prints
the status, the reduction headers, the mesh, the wall time of the request and the
server's peak RSS (``VmHWM``) before and after. Bar: 5,000,000 points (60 MB) give a
valid mesh within 60 s with a peak under 2 GB. ``--format las`` or ``laz`` sends the
same points as a LAS 1.4 file (point format 0, 0.1 mm scale; LAZ compressed) instead.

    python bench/bench_big_cloud.py --points 5000000 10000000 [--format ply|las|laz]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.bench_upload_memory import free_port, start_server, status_kb  # noqa: E402

MB = 2**20


def binary_ply(count: int, seed: int = 0) -> bytes:
    """``count`` float32 points sampled on a torus, as a binary little-endian PLY."""
    from spacemesh.examples import torus_grid
    from spacemesh.primitives import sample_surface

    points, _ = sample_surface(torus_grid(48, 24), count, np.random.default_rng(seed))
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {count}\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n").encode()
    return header + np.asarray(points, dtype="<f4").tobytes()


def las_file(count: int, compressed: bool, seed: int = 0) -> bytes:
    """The points of :func:`binary_ply` as a LAS 1.4 file (point format 0), LAZ when
    ``compressed``."""
    import io

    import laspy

    from spacemesh.examples import torus_grid
    from spacemesh.primitives import sample_surface

    points, _ = sample_surface(torus_grid(48, 24), count, np.random.default_rng(seed))
    header = laspy.LasHeader(point_format=0, version="1.4")
    header.scales = np.full(3, 1e-4)
    header.offsets = points.min(axis=0)
    las = laspy.LasData(header)
    las.x, las.y, las.z = np.asarray(points, dtype=np.float64).T
    out = io.BytesIO()
    las.write(out, do_compress=compressed)
    return out.getvalue()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, nargs="+", default=[5_000_000, 10_000_000])
    parser.add_argument("--format", choices=("ply", "las", "laz"), default="ply")
    args = parser.parse_args()
    import httpx

    port = free_port()
    server = start_server(port, free_port())
    try:
        print(f"server ready, RSS {status_kb(server.pid, 'VmRSS') / 1024:.0f} MB, "
              f"peak {status_kb(server.pid, 'VmHWM') / 1024:.0f} MB")
        print("| points | file MB | status | read -> used | faces | seconds | server peak MB |")
        print("|---:|---:|---|---|---:|---:|---:|")
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=600) as client:
            for count in args.points:
                data = (binary_ply(count) if args.format == "ply"
                        else las_file(count, args.format == "laz"))
                t0 = time.perf_counter()
                response = client.post("/generate", params={"format": "obj"},
                                       files={"file": (f"big.{args.format}", data)})
                seconds = time.perf_counter() - t0
                headers = response.headers
                reduced = (f"{headers.get('x-spacemesh-points-read')} -> "
                           f"{headers.get('x-spacemesh-points-used')}")
                faces = headers.get("x-spacemesh-faces", "?")
                peak = status_kb(server.pid, "VmHWM") / 1024
                print(f"| {count:,} | {len(data) / MB:.0f} | {response.status_code} | "
                      f"{reduced} | {faces} | {seconds:.1f} | {peak:.0f} |", flush=True)
                if response.status_code != 200:
                    print(response.text[:500])
                del data
    finally:
        server.terminate()
        server.wait(60)


if __name__ == "__main__":
    main()
