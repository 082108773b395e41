"""Do repairs add crossing faces? (issue 35: "Repairs add no crossings")

For every closed mesh of one split of the real meshes, a sphere region around a random
vertex (about ``--fraction`` of the vertices, at most ``--cap``; as
``experiments/eval_repair.py`` cuts its CAD cases) is re-generated with
:func:`spacemesh.repair.repair_mesh` at the defaults, and the exact test
(:func:`spacemesh.geometry.intersections.self_intersecting_faces`) counts the faces that
cross in the result but did not in the input: new faces that cross anything, and kept
faces that cross only now. A new face whose every crossing is with a kept face that
already crossed the region's faces in the input (an input whose surfaces pass through
each other there) is counted apart, as inherited. Prints one line per mesh and the
totals.

With ``--holes``, the sphere's faces are removed instead (a hole punched in the mesh)
and the open mesh is repaired with ``{"auto": "holes"}``: the model's passes, then the
fairing or the fallback fills of :mod:`spacemesh.repair.fill` (no inherited count).

Usage::

    python experiments/repair_crossings.py --split dev [--fraction 0.03] [--cap 40]
        [--holes]
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
    parser.add_argument("--holes", action="store_true",
                        help="punch the region out and repair {'auto': 'holes'}")
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from eval_repair import random_region

    from spacemesh.geometry.intersections import crossing_pairs, self_intersecting_faces
    from spacemesh.io import load_mesh
    from spacemesh.primitives import faces_subset, normalize, triangles_of
    from spacemesh.repair import Region, repair_mesh
    from spacemesh.runtime import MeshGenerator

    paths, _ = split_meshes(args.meshes, args.split, set(CATEGORIES))
    generator = MeshGenerator.from_repository(None, threads=1)
    added_meshes = new_total = kept_total = inherited_total = 0
    for index, path in enumerate(paths[: args.limit]):
        mesh, _, _ = normalize(load_mesh(path))
        region = random_region(mesh, np.random.default_rng([args.seed, index]), args.fraction,
                               args.cap)
        if args.holes:  # the region's faces punched out, the holes found automatically
            punched = Region.sphere(**region["sphere"]).face_mask(mesh)
            mesh, _ = faces_subset(mesh, ~punched).remove_unreferenced_vertices()
            region = {"auto": "holes"}
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
        inherited = (inherited_faces(mesh, result, crossing_pairs, triangles_of)
                     if np.any(after & new) and not args.holes else 0)
        new_crossing = int(np.sum(after & new)) - inherited
        added_meshes += (kept_added + new_crossing) > 0
        new_total += new_crossing
        kept_total += kept_added
        inherited_total += inherited
        print(f"{path.name[:40]} | new faces {int(new.sum())}, crossing {new_crossing} "
              f"(inherited {inherited}) | kept faces crossing only now {kept_added} | "
              f"input crossing {int(before.sum())} | faces triangulated again "
              f"{result.stats.fill.get('uncrossed_faces', 0)} | {seconds:.1f} s",
              flush=True)
    print(f"\n{added_meshes} of {min(len(paths), args.limit or len(paths))} repairs add "
          f"crossings: {new_total} new faces cross, {kept_total} kept faces cross only now; "
          f"{inherited_total} new faces cross only kept faces that crossed the region in "
          f"the input")
    return 0


def inherited_faces(mesh, result, crossing_pairs, triangles_of) -> int:
    """New faces of ``result`` whose every crossing is with a kept face that crossed a
    face of the region in ``mesh`` (the input)."""
    triangles, source = triangles_of(mesh)
    before = source[crossing_pairs(mesh.vertices, triangles, source)]  # (P, 2) faces
    region = result.region
    crossed_region = np.zeros(mesh.n_faces, dtype=bool)
    crossed_region[before[region[before[:, 1]], 0]] = True
    crossed_region[before[region[before[:, 0]], 1]] = True
    triangles, source = triangles_of(result.mesh)
    after = source[crossing_pairs(result.mesh.vertices, triangles, source)]  # (Q, 2)
    new = result.face_source < 0
    origin = np.where(new, -1, result.face_source)
    count = 0
    for face in np.flatnonzero(new):
        partners = after[(after == face).any(axis=1)].reshape(-1)
        partners = partners[partners != face]
        if len(partners) and np.all((origin[partners] >= 0)
                                    & crossed_region[np.maximum(origin[partners], 0)]):
            count += 1
    return count


if __name__ == "__main__":
    raise SystemExit(main())
