"""``spacemesh batch`` throughput against the number of workers, and a rerun's cost.

Issue 37 part 6's bar: on 40 clouds plus one corrupt file, 2 workers reach at least 1.7
times the throughput of 1 worker (one thread each), and a rerun on the same output
folder takes at most 25% of the first run's time. This writes ``--clouds`` point clouds
(2,048 points sampled on the bundled example shapes, each scaled, rotated and moved
differently) and one corrupt PLY, then runs the real command line (a fresh process each
time, local Ray included) with ``--workers 1`` and ``--workers 2`` into fresh folders, and
reruns the second. It prints one JSON line per run and the two ratios:

- ``wall_s``: the whole command, Ray's start included;
- ``steady_inputs_per_s``: inputs finished per second between the first and the last
  finished input (from the time each progress line arrives), Ray's start left out.

Timings only; nothing is asserted.

Usage::

    python bench/bench_batch.py [--clouds 40] [--model DIR] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from spacemesh.examples import cube_quads, icosphere, prism, torus_grid
from spacemesh.primitives import sample_surface

CLI = [sys.executable, "-c", "from spacemesh.cli import main; main()"]
#: A progress line of ``spacemesh batch`` (``[ 3/41] ...``).
PROGRESS_LINE = re.compile(r"^\[\s*\d+/\d+\] ")
#: Points per cloud (the shipped model's encoder count).
POINTS = 2048


def write_clouds(folder: Path, count: int) -> None:
    """``count`` XYZ clouds of the example shapes and one corrupt PLY."""
    rng = np.random.default_rng(0)
    shapes = [cube_quads(), prism(6), torus_grid(), icosphere(2)]
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        points, _ = sample_surface(shapes[i % len(shapes)], POINTS, rng)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        points = (points * rng.uniform(0.5, 2.0, 3)) @ q.T + rng.normal(size=3)
        np.savetxt(folder / f"cloud{i:03d}.xyz", points, fmt="%.6f")
    (folder / "corrupt.ply").write_bytes(
        b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1 2\n")


def run(inputs: Path, out: Path, workers: int, model: str | None) -> dict:
    """One ``spacemesh batch`` run: wall time, and finish times of the inputs."""
    command = [*CLI, "batch", str(inputs), "--out", str(out), "--workers", str(workers),
               "--threads-per-worker", "1"] + (["--model", model] if model else [])
    started = time.perf_counter()
    finished = []
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True) as process:
        assert process.stderr is not None and process.stdout is not None
        for line in process.stderr:
            if PROGRESS_LINE.match(line):
                finished.append(time.perf_counter() - started)
        summary = process.stdout.read().strip()
        code = process.wait()
    wall = time.perf_counter() - started
    steady = ((len(finished) - 1) / (finished[-1] - finished[0])
              if len(finished) > 1 and finished[-1] > finished[0] else None)
    return {"workers": workers, "exit_code": code, "wall_s": round(wall, 2),
            "finished": len(finished), "inputs_per_s": round(len(finished) / wall, 3),
            "steady_inputs_per_s": round(steady, 3) if steady else None,
            "summary": summary}


def main() -> None:
    """Run the benchmark and print its figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clouds", type=int, default=40)
    parser.add_argument("--model", default=None, help="Model repository (default shipped).")
    parser.add_argument("--keep", type=Path, default=None,
                        help="Work in this folder and keep it (default: a temporary one).")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        root = args.keep or Path(scratch)
        write_clouds(root / "in", args.clouds)
        one = run(root / "in", root / "out1", 1, args.model)
        print(json.dumps(one), flush=True)
        two = run(root / "in", root / "out2", 2, args.model)
        print(json.dumps(two), flush=True)
        rerun = run(root / "in", root / "out2", 2, args.model)
        print(json.dumps({**rerun, "rerun": True}), flush=True)
    ratios = {
        "wall_speedup_2_vs_1": round(one["wall_s"] / two["wall_s"], 2),
        "steady_speedup_2_vs_1": (round(two["steady_inputs_per_s"]
                                        / one["steady_inputs_per_s"], 2)
                                  if one["steady_inputs_per_s"] and two["steady_inputs_per_s"]
                                  else None),
        "rerun_share_of_first": round(rerun["wall_s"] / two["wall_s"], 3),
    }
    print(json.dumps(ratios))


if __name__ == "__main__":
    main()
