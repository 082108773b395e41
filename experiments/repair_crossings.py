"""Do repairs add crossing faces? (issue 35: "Repairs add no crossings")

For every closed mesh of one split of the real meshes, a sphere region around a random
vertex (about ``--fraction`` of the vertices, at most ``--cap``; as
``experiments/eval_repair.py`` cuts its CAD cases) is re-generated with
:func:`spacemesh.repair.repair_mesh` at the defaults, and the exact test
(:func:`spacemesh.geometry.intersections.self_intersecting_faces`) counts the faces that
cross in the result but did not in the input: new faces that cross anything, and kept
faces that cross only now. Prints one line per mesh and the totals.

Usage::

    python experiments/repair_crossings.py --split dev [--fraction 0.03] [--cap 40]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--fraction", type=float, default=0.03)
    parser.add_argument("--cap", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit", type=int, default=None)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from eval_repair import random_region

    from spacemesh.geometry.intersections import self_intersecting_faces
    from spacemesh.io import load_mesh
    from spacemesh.primitives import normalize
    from spacemesh.repair import repair_mesh
    from spacemesh.runtime import MeshGenerator

    paths, _ = split_meshes(args.meshes, args.split, set(CATEGORIES))
    generator = MeshGenerator.from_repository(None, threads=1)
    added_meshes = new_total = kept_total = 0
    for index, path in enumerate(paths[: args.limit]):
        mesh, _, _ = normalize(load_mesh(path))
        region = random_region(mesh, np.random.default_rng([args.seed, index]), args.fraction,
                               args.cap)
        before = self_intersecting_faces(mesh)  # (F,)
        started = time.perf_counter()
        try:
            result = repair_mesh(mesh, region, generator, seed=args.seed)
        except Exception as error:  # a refusal is a row, not a stop
            print(f"{path.name[:40]} | refused: {str(error)[:80]}", flush=True)
            continue
        seconds = time.perf_counter() - started
        after = self_intersecting_faces(result.mesh)  # (F_out,)
        new = result.face_source < 0
        kept_now = ~new & after
        kept_added = int(np.sum(kept_now & ~before[np.maximum(result.face_source, 0)]))
        new_crossing = int(np.sum(after & new))
        added_meshes += (kept_added + new_crossing) > 0
        new_total += new_crossing
        kept_total += kept_added
        print(f"{path.name[:40]} | new faces {int(new.sum())}, crossing {new_crossing} | "
              f"kept faces crossing only now {kept_added} | input crossing "
              f"{int(before.sum())} | {seconds:.1f} s", flush=True)
    print(f"\n{added_meshes} of {min(len(paths), args.limit or len(paths))} repairs add "
          f"crossings: {new_total} new faces cross, {kept_total} kept faces cross only now")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
