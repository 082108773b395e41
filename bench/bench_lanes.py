"""A small request's latency with and without a heavy one running: the two lanes.

Starts ``spacemesh serve`` (default settings, the shipped model) and sends the small
request (``examples/points.ply``, default options) ``--repeat`` times alone, then again
while the heavy request the default budget admits (``target_vertices=2048&samples=4`` on
a 200,000-point torus cloud) runs, and prints each latency, whether the heavy request was
still running when the small one was answered, and the heavy request's own answer and
time. The same with ``--light-lane-s 0`` (one lane, as before the lanes) for comparison.

Usage::

    python bench/bench_lanes.py [--repeat 3] [--modes default,0] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "points.ply"
HEAVY = "target_vertices=2048&samples=4&seed=0"


def running(url: str, httpx: Any) -> int:
    """Requests in the running batches of both lanes (``spacemesh_lane_running_requests``)."""
    text = httpx.get(url + "/metrics", timeout=10).text
    return int(sum(float(v) for v in re.findall(
        r'^spacemesh_lane_running_requests\{lane="\w+"\} (\S+)$', text, re.M)))


def small(url: str, httpx: Any) -> tuple[int, float]:
    """The small request: status and seconds."""
    started = time.monotonic()
    reply = httpx.post(f"{url}/generate?seed=0", files={"file": ("points.ply",
                                                                 EXAMPLE.read_bytes())},
                       timeout=300)
    return reply.status_code, time.monotonic() - started


def measure(light_lane_s: str | None, repeat: int) -> dict[str, Any]:
    """One server (``--light-lane-s`` from ``light_lane_s``; None: the default)."""
    import httpx

    from bench.bench_big_cloud import binary_ply
    from bench.bench_upload_memory import free_port, start_server

    if light_lane_s is None:
        os.environ.pop("SPACEMESH_LIGHT_LANE_S", None)
    else:
        os.environ["SPACEMESH_LIGHT_LANE_S"] = light_lane_s
    port = free_port()
    server = start_server(port, free_port())
    url = f"http://127.0.0.1:{port}"
    big = binary_ply(200_000)
    row: dict[str, Any] = {"light_lane_s": light_lane_s or "default"}
    try:
        row["alone"] = [small(url, httpx) for _ in range(repeat)]
        heavy: dict[str, Any] = {}

        def send_heavy() -> None:
            started = time.monotonic()
            reply = httpx.post(f"{url}/generate?{HEAVY}", files={"file": ("big.ply", big)},
                               timeout=300)
            heavy.update(status=reply.status_code, seconds=time.monotonic() - started)

        thread = threading.Thread(target=send_heavy)
        thread.start()
        while not running(url, httpx):  # the heavy request runs
            time.sleep(0.05)
        during = []
        for _ in range(repeat):
            status, seconds = small(url, httpx)
            during.append((status, seconds, "status" not in heavy))
        thread.join()
        row["during"], row["heavy"] = during, heavy
    finally:
        server.terminate()
        server.wait(60)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--modes", default="default,0",
                        help="--light-lane-s values, 'default' for the default")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    rows = []
    for mode in args.modes.split(","):
        row = measure(None if mode == "default" else mode, args.repeat)
        rows.append(row)
        alone = ", ".join(f"{s:.2f} s" for _, s in row["alone"])
        during = ", ".join(f"{st} after {s:.2f} s{' (heavy running)' if r else ''}"
                           for st, s, r in row["during"])
        print(f"--light-lane-s {row['light_lane_s']}: small alone {alone}; while the heavy "
              f"one runs {during}; heavy {row['heavy']['status']} after "
              f"{row['heavy']['seconds']:.1f} s", flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
