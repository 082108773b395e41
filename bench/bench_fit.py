"""Fitting speed at about 10,000 vertices (issue target: exact within 600 iterations, < 120 s).

Fits the built-in 10,242-vertex icosphere (and optionally a mesh file) with the default
settings and prints iterations, seconds and the time per iteration.

Usage::

    python bench/bench_fit.py [--threads 2] [--mesh FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import torch

from spacemesh.examples import icosphere, torus_grid
from spacemesh.fitting import EmbeddingFitConfig, fit_mesh
from spacemesh.io import load_mesh


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--mesh", default=None, help="a mesh file instead of the built-ins")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    meshes = (
        {args.mesh: load_mesh(args.mesh)}
        if args.mesh
        else {
            "icosphere(5), triangles": icosphere(5),
            "torus 100 x 100, quads": torus_grid(100, 100),
        }
    )
    for name, mesh in meshes.items():
        start = time.perf_counter()
        result = fit_mesh(mesh, EmbeddingFitConfig(threads=args.threads))
        wall = time.perf_counter() - start
        summary = result.summary()
        summary.update(
            mesh=name,
            threads=args.threads,
            wall_seconds=round(wall, 2),
            ms_per_iteration=round(1000 * result.seconds / result.iterations, 1),
        )
        print(json.dumps(summary), flush=True)


if __name__ == "__main__":
    main()
