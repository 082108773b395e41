"""Vertex-fit settings for noisy points: CD against the truth, per variant (issue 36).

On every mesh of one split of the real meshes (2,048 bare points, sampled and corrupted
exactly as ``experiments/eval_real_meshes.py`` does), the shipped pipeline runs at its
defaults with each variant's :class:`spacemesh.geometry.fitting.VertexFitOptions`
fields replaced, and the script prints each variant's mean and median CD, topology
agreement and mean time. Tune on ``dev`` only.

Usage::

    python experiments/noise_fit_sweep.py --split dev --noise 0.01 \\
        --variant 'shipped={}' --variant 'k24={"plane_neighbours": 24}'
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--noise", type=float, default=0.01)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--variant", action="append", default=[],
                        help="NAME=JSON of VertexFitOptions fields")
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from spacemesh.evaluate.runner import corrupt_points, mesh_shapes
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.metrics.sampling import apply_normalisation, normalisation
    from spacemesh.runtime import MeshGenerator

    variants = dict(v.split("=", 1) for v in (args.variant or ["shipped={}"]))
    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=args.seed)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=1)
    shipped = generator.spec
    rows: dict[str, list[tuple[float, bool, float]]] = {name: [] for name in variants}
    for index, shape in enumerate(shapes):
        centre, scale = normalisation(shape.mesh)
        gt = apply_normalisation(shape.mesh, centre, scale)
        points = (np.asarray(shape.points, np.float64) - centre) / scale
        points = corrupt_points(points, noise=args.noise, seed=[args.seed, index])
        reference = Reference.from_mesh(gt, seed=[args.seed, index, 0])
        line = [shape.shape_id[:32]]
        for name, fields in variants.items():
            fit = replace(shipped.geometry.fit, **json.loads(fields))
            generator.spec = replace(shipped, geometry=replace(shipped.geometry, fit=fit))
            started = time.perf_counter()
            result = generator.generate(points, None, seed=args.seed)
            seconds = time.perf_counter() - started
            row = score_mesh(result.mesh, reference)
            rows[name].append((float(row["cd"]), bool(row["topology"]), seconds))
            line.append(f"{name} {row['cd'] * 1e3:.3f}")
        print(" | ".join(line), flush=True)
    print()
    for name, values in rows.items():
        cds = [v[0] * 1e3 for v in values]
        print(f"{name}: CD {statistics.mean(cds):.3f} (median {statistics.median(cds):.3f}), "
              f"topology {sum(v[1] for v in values)}/{len(values)}, "
              f"{statistics.mean(v[2] for v in values):.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
