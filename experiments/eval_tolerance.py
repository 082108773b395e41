"""Does ``tolerance`` hold against the truth? The real meshes of one split, from bare points.

For every closed mesh of the split (as ``eval_real_meshes.py`` picks them: normalised,
2,048 points sampled on it), generate with ``tolerance`` and measure the mean distance
from the *ground truth* (20,000 points sampled on it) to the mesh's surface, as a
fraction of the ground truth's bounding-box diagonal. The bar of issue #34: at most the
tolerance on at least 90% of the shapes. Prints one line per mesh and the summary
(share within the tolerance, share whose fit report met it, vertices, seconds).

Usage::

    python experiments/eval_tolerance.py --split test --tolerance 0.005 [--threads 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from eval_real_meshes import CATEGORIES, split_meshes

ROOT = Path(__file__).resolve().parents[1]
#: Ground-truth samples per mesh.
TRUTH_SAMPLES = 20_000


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument("--split", choices=("dev", "test", "all"), default="test")
    parser.add_argument("--categories", default=",".join(CATEGORIES))
    parser.add_argument("--tolerance", type=float, default=0.005)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--margin", type=float, default=None,
                        help="the search's aim as a fraction of the tolerance (default: "
                             "spacemesh.runtime.tolerance.TOLERANCE_MARGIN)")
    parser.add_argument("--simplify-share", type=float, default=None,
                        help="the simplified mesh's distance before its fit, in aims "
                             "(default: spacemesh.geometry.finishing.SIMPLIFY_SHARE)")
    parser.add_argument("--local-share", type=float, default=None,
                        help="the most one collapse may cost, in aims (default: "
                             "spacemesh.geometry.simplify.LOCAL_DISTANCE_SHARE)")
    args = parser.parse_args()
    if not (args.meshes / "manifest.csv").is_file():
        print(f"skipped: {args.meshes / 'manifest.csv'} not found")
        return 0

    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.evaluate.runner import mesh_shapes
    from spacemesh.metrics.sampling import apply_normalisation, normalisation
    from spacemesh.primitives import sample_surface, triangles_of
    from spacemesh.primitives.closest import nearest_triangles
    from spacemesh.runtime import MeshGenerator
    from spacemesh.runtime import tolerance as tolerance_search

    if args.margin is not None:
        tolerance_search.TOLERANCE_MARGIN = args.margin
    from spacemesh.geometry import finishing

    if args.simplify_share is not None:
        finishing.SIMPLIFY_SHARE = args.simplify_share
    if args.local_share is not None:
        from spacemesh.geometry import simplify as simplification
        simplification.LOCAL_DISTANCE_SHARE = args.local_share

    paths, categories = split_meshes(args.meshes, args.split, set(args.categories.split(",")))
    shapes = mesh_shapes(paths, categories=categories, seed=args.seed)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=args.threads)
    within, met, counts, seconds = [], [], [], []
    for index, shape in enumerate(shapes):
        centre, scale = normalisation(shape.mesh)
        truth = apply_normalisation(shape.mesh, centre, scale)
        points = (np.asarray(shape.points, np.float64) - centre) / scale
        start = time.perf_counter()
        result = generator.generate(points, None, seed=args.seed, tolerance=args.tolerance)
        seconds.append(time.perf_counter() - start)
        samples, _ = sample_surface(truth, TRUTH_SAMPLES, np.random.default_rng([args.seed, index]))
        triangles, _ = triangles_of(result.mesh)
        _, gap = nearest_triangles(samples.astype(np.float64), result.mesh.vertices, triangles)
        diagonal = float(np.linalg.norm(np.ptp(truth.vertices, axis=0)))
        distance = float(np.sqrt(np.maximum(gap, 0.0)).mean()) / diagonal
        within.append(distance <= args.tolerance)
        met.append(bool(result.fit is not None and result.fit.tolerance_met))
        counts.append(result.mesh.n_vertices)
        print(f"{shape.shape_id[:48]:48s} {shape.category:11s} truth->mesh {distance:.5f} "
              f"({'ok' if within[-1] else 'OVER'}), fit met {met[-1]}, "
              f"{counts[-1]} vertices, {len(result.tolerance_tries)} tries, "
              f"{seconds[-1]:.1f} s", flush=True)
    print(f"\n{args.split} split, tolerance {args.tolerance:g}, margin "
          f"{tolerance_search.TOLERANCE_MARGIN:g}, {len(shapes)} meshes: "
          f"truth->mesh within it on {100 * np.mean(within):.0f}%, fit report met on "
          f"{100 * np.mean(met):.0f}%; vertices median {np.median(counts):.0f} "
          f"(mean {np.mean(counts):.0f}); seconds median {np.median(seconds):.1f}, "
          f"max {np.max(seconds):.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
