"""The independent self-intersection check of issue 35 on default outputs.

Generates every closed mesh of one split of the real meshes from 2,048 bare points (the
evaluation's sampling, seed 0, the shipped model's defaults) and runs PyMeshLab's
per-face self-intersection filter (``compute_selection_by_self_intersections_per_face``)
on each output (the default outputs are triangles; a polygon would be read as
:func:`spacemesh.primitives.triangles_of` reads it): the issue's own check, independent
of :mod:`spacemesh.geometry.intersections`. Prints the crossing faces
of each output and how many outputs have any. PyMeshLab (GPL) is a test dependency
only, never the serving install's.

Usage::

    python experiments/independent_crossings.py --split test
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    args = split_parser(__doc__).parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from spacemesh.data.validate import pymeshlab_selected_triangles
    from spacemesh.evaluate.runner import mesh_shapes
    from spacemesh.primitives import triangles_of
    from spacemesh.runtime import MeshGenerator

    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    generator = MeshGenerator.from_repository(None, threads=1)
    crossing_outputs = 0
    shapes = mesh_shapes(paths, categories=categories, seed=0)
    for shape in shapes:
        mesh = generator.generate(shape.points, None, seed=0).mesh
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
