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

``--explain`` also says how many of the faces it selects come from pairs of exactly
coplanar triangles (corners within 1e-12 of the diagonal of the other's plane) that
PyMeshLab's filter reads as crossing although they do not overlap (their overlap area,
by clipping one with the other in their plane, under 1e-9 of the smaller's area): the
filter's false positives on flat regions (docs/GEOMETRY.md, "PyMeshLab on flat regions").

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


def _clipped_area(subject: np.ndarray, clipper: np.ndarray) -> float:
    """Area of ``subject`` (K, 2) clipped by the convex counter-clockwise ``clipper``
    (3, 2) (Sutherland-Hodgman)."""
    polygon = list(subject)
    for k in range(len(clipper)):
        a, b = clipper[k], clipper[(k + 1) % len(clipper)]

        def side(q, a=a, b=b):
            return (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])

        kept = []
        for m, q in enumerate(polygon):
            prev = polygon[m - 1]
            if side(q) >= 0:
                if side(prev) < 0:
                    kept.append(prev + side(prev) / (side(prev) - side(q)) * (q - prev))
                kept.append(q)
            elif side(prev) >= 0:
                kept.append(prev + side(prev) / (side(prev) - side(q)) * (q - prev))
        polygon = kept
        if len(polygon) < 3:
            return 0.0
    x, y = np.array(polygon).T
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))


def flat_false_positives(vertices: np.ndarray, triangles: np.ndarray,
                         selected: np.ndarray) -> int:
    """How many of the ``selected`` triangles PyMeshLab pairs with an exactly coplanar
    one that it reads as crossing but that does not overlap it (module docstring)."""
    from scipy.spatial import cKDTree

    from spacemesh.data.validate import pymeshlab_selected_triangles

    corners = vertices[triangles[selected]]  # (S, 3, 3)
    diagonal = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    centre = corners.mean(axis=1)
    reach = 2 * float(np.linalg.norm(corners - centre[:, None], axis=2).max())
    explained: set[int] = set()
    for a, b in cKDTree(centre).query_pairs(reach):
        ta, tb = corners[a], corners[b]
        normal = np.cross(ta[1] - ta[0], ta[2] - ta[0])
        if not np.linalg.norm(normal) > 0:
            continue  # a triangle without area has no plane: not explained here
        normal /= np.linalg.norm(normal)
        if np.abs((tb - ta[0]) @ normal).max() > 1e-12 * diagonal:
            continue
        axis_u = (ta[1] - ta[0]) / np.linalg.norm(ta[1] - ta[0])
        axis_v = np.cross(normal, axis_u)
        flat = [np.stack([(t - ta[0]) @ axis_u, (t - ta[0]) @ axis_v], axis=1)
                for t in (ta, tb)]  # (3, 2) each
        flat = [f if np.cross(f[1] - f[0], f[2] - f[0]) > 0 else f[::-1] for f in flat]
        smaller = min(0.5 * abs(float(np.cross(f[1] - f[0], f[2] - f[0]))) for f in flat)
        if _clipped_area(flat[1], flat[0]) > 1e-9 * smaller:
            continue  # they overlap: a crossing
        pair = np.stack([triangles[selected[a]], triangles[selected[b]]])
        if len(pymeshlab_selected_triangles(vertices, pair)):
            explained.update((a, b))
    return len(explained)


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--data", type=Path, default=None,
                        help="a synthetic dataset folder instead of the real meshes")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--partial", action="store_true", help="one-sided scans")
    parser.add_argument("--gt-count", action="store_true",
                        help="target_vertices = the ground truth's count")
    parser.add_argument("--explain", action="store_true",
                        help="count the selected faces that are flat false positives")
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
        explained = ""
        if args.explain and faces:
            flat = flat_false_positives(mesh.vertices, triangles, selected)
            explained = f" ({flat} of the {len(selected)} triangles: flat false positives)"
        print(f"{shape.shape_id[:48]:<48} crossing faces {faces} of {mesh.n_faces}{explained}",
              flush=True)
    print(f"\n{crossing_outputs} of {len(shapes)} outputs have crossing faces (PyMeshLab)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
