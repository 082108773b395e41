"""What the geometry stage and the fit report cost, and the end-to-end time per mode.

Generates from 2,048 points sampled on three shapes made in code (a box, a cylinder, a
torus) with the shipped model, in the modes ``raw``, default, default with the points'
normals (the geometry stage then runs with and without them), ``samples=4``,
``target_vertices=1000`` and ``2000``, ``tolerance=0.002`` and the dense decode at other
factors than the shipped model's 2 (``GeometryOptions.dense_factor`` 1, the decode at the
count asked for, and 4; issue 47), several seeds each, and prints the
median seconds of every stage and of the whole call (every seed and try the request ran
included), and how many calls tried more seeds because the mesh's pieces disagreed with
the points'. ``--meshes FILE...`` times real meshes too (2,048
points sampled on each, the default path with every step). Issue targets (2-core
machine, quiet): default <= 1.0 s, ``samples=4`` <= 2.5 s; issue 34: the default path
with every step <= 2 s per mesh (``--threads 0``).

Usage::

    python bench/bench_geometry.py [--threads 0] [--repeats 5] [--model MODEL_DIR]
        [--meshes FILE ...] [--modes default,tolerance=0.002]
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--model", default=None)
    parser.add_argument("--meshes", nargs="*", default=[],
                        help="mesh files to time as well (the default path)")
    parser.add_argument("--modes", default=None,
                        help="comma-separated modes to time (default: all), e.g. "
                             "'default,tolerance=0.002'")
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.examples import cube_quads, prism, torus_grid
    from spacemesh.io import load_mesh
    from spacemesh.primitives import sample_surface
    from spacemesh.runtime import MeshGenerator

    generator = MeshGenerator.from_repository(args.model, threads=args.threads)
    box = cube_quads()
    shapes = {"box": box.with_vertices(box.vertices * [2.0, 1.0, 0.6]),
              "cylinder": prism(32), "torus": torus_grid(32, 16)}
    modes = {"raw": {"raw": True}, "default": {}, "default, normals": {},
             "samples=4": {"samples": 4}, "target_vertices=1000": {"target_vertices": 1000},
             "target_vertices=2000": {"target_vertices": 2000},
             "tolerance=0.002": {"tolerance": 0.002}, "dense_factor=1": {},
             "dense_factor=4": {}}
    if args.modes is not None:
        wanted = args.modes.split(",")
        unknown = sorted(set(wanted) - set(modes))
        if unknown:
            parser.error(f"unknown modes {unknown}; known: {', '.join(modes)}")
        modes = {mode: modes[mode] for mode in wanted}
    print(f"model {generator.name} ({generator.repository.path}), {args.threads} threads, "
          f"{args.repeats} seeds per shape")
    print(f"{'mode':<22}{'total s':>9}{'wall s':>9}{'retried':>9}  median stage seconds")
    for mode, options in modes.items():
        clouds = []
        for index, mesh in enumerate(shapes.values()):
            points, normals = sample_surface(mesh, 2048, np.random.default_rng(index))
            clouds.append((points, normals if mode.endswith("normals") else None))
        spec = generator.spec
        if mode.startswith("dense_factor="):  # another dense decode factor (issue 47)
            factor = float(mode.split("=")[1])
            generator.spec = replace(spec, geometry=replace(spec.geometry,
                                                            dense_factor=factor))
        try:
            _time(generator, mode, clouds, options, args.repeats)
        finally:
            generator.spec = spec
    if args.meshes:
        clouds = []
        for index, path in enumerate(args.meshes):
            points, _ = sample_surface(load_mesh(path), 2048, np.random.default_rng(index))
            clouds.append((points, None))
        _time(generator, f"default, {len(clouds)} files", clouds, {}, args.repeats)


def _time(generator, mode: str, clouds: list, options: dict, repeats: int) -> None:
    """Print one mode's line: median seconds (total, wall, per stage) over every cloud
    and seed, and the calls whose pieces retry ran."""
    stages: dict[str, list[float]] = {}
    walls, retried = [], 0
    for points, normals in clouds:
        generator.generate(points, normals, seed=0, **options)  # warm-up
        for seed in range(repeats):
            start = time.perf_counter()
            result = generator.generate(points, normals, seed=seed, **options)
            walls.append(time.perf_counter() - start)
            retried += len(result.sample_scores) > options.get("samples", 1)
            for key, value in result.timings.items():
                stages.setdefault(key, []).append(value)
    detail = "  ".join(f"{k} {np.median(v):.3f}" for k, v in stages.items() if k != "total")
    print(f"{mode:<22}{np.median(stages['total']):>9.3f}{np.median(walls):>9.3f}"
          f"{f'{retried}/{len(walls)}':>9}  {detail}", flush=True)

if __name__ == "__main__":
    main()
