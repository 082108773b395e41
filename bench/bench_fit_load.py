"""``spacemesh fit`` at about 10,000 vertices, alone and against a competing CPU load.

Issue 20 (steady under load): the 10k fit took 20x longer with other work on the
machine, far beyond what the load explains. This runs the same fit (the built-in
10,242-vertex icosphere, or ``--mesh``) through the real command line (a fresh process
each time, so that thread settings apply when torch loads):

1. alone;
2. with one busy process per core (``--load`` of them) competing for the CPU;
3. with ``--spin``, the loaded run again with OpenMP's threads spinning while they wait
   (``OMP_WAIT_POLICY=ACTIVE``), and with ``--libgomp-default``, with the wait policy
   left to OpenMP (``OMP_WAIT_POLICY`` set but empty, so that ``spacemesh.threads`` does
   not choose PASSIVE: the behaviour before it), for comparison.

and prints one JSON line per run (the fit's ``--json`` summary plus the wall time), then
the slowdown of each loaded run. Timings only; nothing is asserted.

Usage::

    python bench/bench_fit_load.py [--threads 0] [--load N] [--mesh FILE] [--spin]
        [--libgomp-default] [--timeout SECONDS]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from spacemesh.examples import icosphere
from spacemesh.io import save_mesh
from spacemesh.threads import default_threads

BUSY = "while True:\n    pass\n"


def run_fit(mesh: Path, threads: int, max_iters: int, env: dict[str, str],
            timeout: float) -> dict:
    """One ``spacemesh fit --json`` in a fresh process; its summary plus the wall time
    (``timed_out`` and no summary when it ran past ``timeout`` seconds)."""
    command = [sys.executable, "-m", "spacemesh.cli", "fit", str(mesh), "--json",
               "--threads", str(threads), "--max-iters", str(max_iters)]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, capture_output=True, text=True, env=env,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"timed_out": True, "wall_seconds": round(time.perf_counter() - start, 2)}
    wall = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise SystemExit(f"spacemesh fit failed: {done.stderr.strip()[-2000:]}")
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    summary["wall_seconds"] = round(wall, 2)
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=0,
                        help="--threads of the fit (0: one per core)")
    parser.add_argument("--load", type=int, default=default_threads(),
                        help="busy processes of the competing load (default: one per core)")
    parser.add_argument("--mesh", type=Path, default=None, help="a mesh file (default: "
                        "the 10,242-vertex icosphere)")
    parser.add_argument("--max-iters", type=int, default=1000)
    parser.add_argument("--spin", action="store_true",
                        help="also run loaded with OMP_WAIT_POLICY=ACTIVE (spinning threads)")
    parser.add_argument("--libgomp-default", action="store_true",
                        help="also run loaded with OpenMP's own wait policy (as before)")
    parser.add_argument("--timeout", type=float, default=1800.0,
                        help="seconds after which one fit is stopped and reported as such")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        mesh = args.mesh
        if mesh is None:
            mesh = Path(tmp) / "icosphere5.ply"
            save_mesh(icosphere(5), mesh)
        env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
        runs = [("alone", env, False), ("loaded", env, True)]
        if args.libgomp_default:
            runs.append(("loaded, OpenMP's default wait", {**env, "OMP_WAIT_POLICY": ""}, True))
        if args.spin:
            runs.append(("loaded, spinning", {**env, "OMP_WAIT_POLICY": "ACTIVE"}, True))
        results = {}
        for name, run_env, loaded in runs:
            busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(args.load)
                    ] if loaded else []
            try:
                summary = run_fit(mesh, args.threads, args.max_iters, run_env, args.timeout)
            finally:
                for process in busy:
                    process.kill()
                    process.wait()
            summary.update(run=name, threads=args.threads or default_threads(),
                           load_processes=len(busy), cores=default_threads())
            results[name] = summary
            print(json.dumps(summary), flush=True)
        alone = results["alone"]["wall_seconds"]
        for name, summary in results.items():
            if name != "alone":
                more = "more than " if summary.get("timed_out") else ""
                print(f"{name}: {more}{summary['wall_seconds']:.1f} s against {alone:.1f} s "
                      f"alone ({more}{summary['wall_seconds'] / alone:.2f}x)", flush=True)


if __name__ == "__main__":
    main()
