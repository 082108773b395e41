"""The independent self-intersection check of issue 35 on default outputs.

Generates every closed mesh of one split of the real meshes (or of a synthetic dataset,
``--data``) from 2,048 bare points (the evaluation's sampling, seed 0, the shipped
model's defaults; ``--partial``: the one-sided scans of ``eval_one_sided.py``, the points whose true
normal has a positive component along an axis direction;
``--gt-count``: ``target_vertices`` the ground truth's count) and runs PyMeshLab's
per-face self-intersection filter (``compute_selection_by_self_intersections_per_face``)
on each output (the default outputs are triangles; a polygon would be read as
:func:`spacemesh.primitives.triangles_of` reads it): the issue's own check, independent
of :mod:`spacemesh.geometry.intersections`. Prints the crossing faces
of each output and how many outputs have any. PyMeshLab (GPL) is a test dependency
only, never the serving install's.

Usage::

    python experiments/independent_crossings.py --split test [--partial] [--gt-count]
    python experiments/independent_crossings.py --data DATASET [--limit 50] [--gt-count]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_one_sided import DIRECTIONS
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--data", type=Path, default=None,
                        help="a synthetic dataset folder instead of the real meshes")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--partial", action="store_true", help="one-sided scans")
    parser.add_argument("--gt-count", action="store_true",
                        help="target_vertices = the ground truth's count")
    args = parser.parse_args()
    from spacemesh.evaluate.runner import load_shapes, pin_threads

    pin_threads(1)
    from spacemesh.data.validate import pymeshlab_selected_triangles
    from spacemesh.evaluate.runner import mesh_shapes
    from spacemesh.metrics.scans import one_sided
    from spacemesh.primitives import triangles_of
    from spacemesh.runtime import MeshGenerator

    if args.data is None:
        paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
        shapes = mesh_shapes(paths, categories=categories, seed=0)
    else:
        shapes = load_shapes(args.data, split="all", limit=args.limit)
    generator = MeshGenerator.from_repository(None, threads=1)
    crossing_outputs = 0
    for index, shape in enumerate(shapes):
        assert shape.normals is not None or not args.partial
        points = (shape.points[one_sided(shape.normals, DIRECTIONS[index % len(DIRECTIONS)])]
                  if args.partial else shape.points)  # (P', 3)
        extra = {"target_vertices": shape.mesh.n_vertices} if args.gt_count else {}
        mesh = generator.generate(points, None, seed=0, **extra).mesh
        triangles, source = triangles_of(mesh)  # (T, 3), (T,)
        selected = pymeshlab_selected_triangles(mesh.vertices, triangles)
        faces = len(np.unique(source[selected]))
        crossing_outputs += faces > 0
        print(f"{shape.shape_id[:48]:<48} crossing faces {faces} of {mesh.n_faces}",
              flush=True)
    print(f"\n{crossing_outputs} of {len(shapes)} outputs have crossing faces (PyMeshLab)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
