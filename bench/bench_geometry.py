"""What the geometry stage and the fit report cost, and the end-to-end time per mode.

Generates from 2,048 points sampled on three shapes made in code (a box, a cylinder, a
torus) with the shipped model, in the modes ``raw``, default and ``samples=4`` (and
``target_vertices=1000``), several seeds each, and prints the median seconds of every
stage and of the whole call. Issue targets (2-core machine, quiet): default <= 1.0 s,
``samples=4`` <= 2.5 s.

Usage::

    python bench/bench_geometry.py [--threads 2] [--repeats 5] [--model MODEL_DIR]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--model", default=None)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.examples import cube_quads, prism, torus_grid
    from spacemesh.primitives import sample_surface
    from spacemesh.runtime import MeshGenerator

    generator = MeshGenerator.from_repository(args.model, intra_op_threads=args.threads)
    box = cube_quads()
    shapes = {"box": box.with_vertices(box.vertices * [2.0, 1.0, 0.6]),
              "cylinder": prism(32), "torus": torus_grid(32, 16)}
    modes = {"raw": {"raw": True}, "default": {}, "samples=4": {"samples": 4},
             "target_vertices=1000": {"target_vertices": 1000}}
    print(f"model {generator.name} ({generator.repository.path}), {args.threads} threads, "
          f"{args.repeats} seeds per shape")
    print(f"{'mode':<22}{'total s':>9}{'wall s':>9}  median stage seconds")
    for mode, options in modes.items():
        stages: dict[str, list[float]] = {}
        walls = []
        for index, mesh in enumerate(shapes.values()):
            points, _ = sample_surface(mesh, 2048, np.random.default_rng(index))
            generator.generate(points, seed=0, **options)  # warm-up
            for seed in range(args.repeats):
                start = time.perf_counter()
                result = generator.generate(points, seed=seed, **options)
                walls.append(time.perf_counter() - start)
                for key, value in result.timings.items():
                    stages.setdefault(key, []).append(value)
        detail = "  ".join(f"{k} {np.median(v):.3f}" for k, v in stages.items() if k != "total")
        print(f"{mode:<22}{np.median(stages['total']):>9.3f}{np.median(walls):>9.3f}  {detail}")


if __name__ == "__main__":
    main()
