"""Latency and peak memory against the vertex count, for the default pipeline and raw.

One generator shape (``qem`` style, seed 11, 1,024 to 2,048 vertices; 8,192 points on
it, no normals) goes through ``MeshGenerator.generate(points, target_vertices=N)`` for
each N and mode, ``--repeats`` times after one warm-up call. Every (mode, N) runs in a
fresh process, so its peak resident memory (``ru_maxrss``: model, onnxruntime arenas,
numpy) is its own. Modes:

- ``default``: what a user gets (``ModelSpec.large_meshes``, ``tokens`` for the shipped
  model: every vertex up to 2,048 through the connectivity network, then the geometry
  stage);
- ``split``: the default before large meshes (256 tokens, the stage splits edges);
- ``raw``: every vertex through the networks, no geometry stage.

Usage::

    OMP_NUM_THREADS=1 python bench/bench_vertex_count.py --threads 2 --repeats 5 \
        --targets 256,512,1024,2048 --modes default,split,raw

The machine's load average is printed with the table: the figures are only comparable
on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

POINTS = 8192
STAGES = ("connectivity", "extraction", "geometry", "report")


def make_cloud(path: Path) -> None:
    """The benchmark's points (the generator shape of seed 11, index 0) in ``path``."""
    from spacemesh.data.synth import SynthConfig, make_shape
    from spacemesh.primitives import normalize, sample_surface

    config = SynthConfig(count=1, seed=11, style="qem", vertex_min=1024, vertex_max=2048,
                         points=POINTS)
    shape, _, _ = make_shape(config, 0)
    mesh, _, _ = normalize(shape["mesh"])
    points, _ = sample_surface(mesh, POINTS, np.random.default_rng([11, 0]))
    np.save(path, np.asarray(points, np.float64))


def child(args: argparse.Namespace) -> None:
    """Time one (mode, target) in this process and print one JSON line."""
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.runtime import MeshGenerator

    points = np.load(args.cloud)
    generator = MeshGenerator.from_repository(threads=args.threads)
    if args.mode == "split":
        generator.spec = replace(generator.spec, large_meshes="split")
    raw = args.mode == "raw"
    generator.generate(points, target_vertices=args.target, raw=raw)  # warm-up
    totals, stages, vertices = [], {s: [] for s in STAGES}, 0
    for repeat in range(args.repeats):
        start = time.perf_counter()
        result = generator.generate(points, seed=repeat, target_vertices=args.target, raw=raw)
        totals.append(time.perf_counter() - start)
        for name in STAGES:
            stages[name].append(result.timings.get(name, 0.0))
        vertices = result.mesh.n_vertices
    print(json.dumps({
        "median": float(np.median(totals)), "p90": float(np.percentile(totals, 90)),
        "stages": {k: float(np.median(v)) for k, v in stages.items()},
        "vertices": int(vertices),
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", default="256,512,1024,2048")
    parser.add_argument("--modes", default="default,split,raw")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--mode", default="default", help=argparse.SUPPRESS)
    parser.add_argument("--target", type=int, default=256, help=argparse.SUPPRESS)
    parser.add_argument("--cloud", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return 0
    with tempfile.TemporaryDirectory() as folder:
        cloud = Path(folder) / "cloud.npy"
        make_cloud(cloud)
        print(f"threads {args.threads}, repeats {args.repeats}, load average at start "
              f"{os.getloadavg()[0]:.1f}")
        print("\n| mode | target | #V | median s | p90 s | connectivity s | decode s | "
              "geometry s | report s | peak MiB |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for mode in args.modes.split(","):
            for target in (int(t) for t in args.targets.split(",")):
                out = subprocess.run(
                    [sys.executable, __file__, "--child", "--mode", mode, "--target",
                     str(target), "--cloud", str(cloud), "--threads", str(args.threads),
                     "--repeats", str(args.repeats)],
                    capture_output=True, text=True, check=True,
                )
                row = json.loads(out.stdout.strip().splitlines()[-1])
                s = row["stages"]
                print(f"| {mode} | {target} | {row['vertices']} | {row['median']:.2f} | "
                      f"{row['p90']:.2f} | {s['connectivity']:.2f} | {s['extraction']:.2f} | "
                      f"{s['geometry']:.2f} | {s['report']:.2f} | {row['peak_mib']:.0f} |",
                      flush=True)
        print(f"\nload average at end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
