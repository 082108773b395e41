"""Does the fit report tell a mesh that lost a handle? (issue 47, clause 3)

For each shape (a synthetic dataset's first ``--limit`` parts, or a split of the real
meshes), one default generate from the bare points (seed 0), and one line: the ground
truth's genus, the output's, the fit report's 95th percentile and mean of the distance
from the points to the mesh (over the diagonal), its coverage, and how many seeds ran.
A handle the decode closed over would leave the points on the hole's walls off the
mesh; if that showed in the report, the seeds' check could ask for more seeds there.

Usage::

    python experiments/fit_signal_of_lost_handles.py --data data/qemflip-tune-s3
    python experiments/fit_signal_of_lost_handles.py --split dev
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--data", default=None, help="a synthetic dataset instead")
    parser.add_argument("--limit", type=int, default=50)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import load_shapes, mesh_shapes, pin_threads

    pin_threads(1)
    from spacemesh.runtime import MeshGenerator
    from spacemesh.topology import surface_topology

    if args.data is not None:
        shapes = load_shapes(args.data, split="all", limit=args.limit)
    else:
        paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
        shapes = mesh_shapes(paths, categories=categories, seed=0)
    generator = MeshGenerator.from_repository(None, threads=1)
    print("shape | right | truth genus | genus | p95 | mean | coverage | seeds")
    for shape in shapes:
        truth = surface_topology(shape.mesh)
        result = generator.generate(shape.points, seed=0)
        fit = result.fit
        assert fit is not None
        right = (fit.pieces, fit.genus) == (truth.pieces, truth.genus)
        print(f"{shape.shape_id[:40]} | {right} | {truth.genus} | {fit.genus} | "
              f"{fit.points_to_mesh_p95_rel:.5f} | {fit.points_to_mesh_mean_rel:.5f} | "
              f"{fit.coverage:.3f} | {len(result.sample_scores or [])}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
