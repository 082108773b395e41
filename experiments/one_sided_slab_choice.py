"""Trial (issue 36, 2026-12-08; dropped): a one-sided scan's slab decode as another
candidate, with the runtime measures a choice could read.

Where ``surface=auto`` opens the default output, the points get a copy pushed back by
each ``--thickness`` of the diagonal along their normals (estimated, oriented like the
nearest face of the opened output), the slab is decoded closed and trimmed to the
original points (as ``experiments/one_sided_thicken.py``). Each mesh is scored as
``experiments/eval_one_sided.py`` scores, beside what the service could measure without
the truth: the mean distance from the points to the mesh (``p2m``) and from the mesh to
the points (``m2p``), in mean point spacings, and the share of points farther than two
spacings (``unc``). On dev, choosing by ``p2m + m2p`` gave completeness 1.36 -> 1.16-1.20e-2
and accuracy 0.89 -> 0.97-1.00 (docs/GEOMETRY.md, "Tried on the way to the two
candidates").

Usage::

    python experiments/one_sided_slab_choice.py --split dev [--thickness 0.05,0.1]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))


def main() -> int:
    from eval_one_sided import DIRECTIONS
    from eval_real_meshes import CATEGORIES, split_meshes, split_parser

    parser = split_parser(__doc__)
    parser.add_argument("--thickness", default="0.05,0.1")
    args = parser.parse_args()
    from spacemesh.evaluate.runner import mesh_shapes, pin_threads

    pin_threads(1)
    from scipy.spatial import cKDTree

    from spacemesh.geometry.fitting import estimate_point_normals
    from spacemesh.geometry.surface import shape_surface
    from spacemesh.metrics.scans import one_sided, scan_scores
    from spacemesh.primitives import sample_surface, triangles_of
    from spacemesh.primitives.closest import mean_spacing, nearest_triangles
    from spacemesh.runtime import MeshGenerator

    def measures(mesh, points):
        """(p2m, unc, m2p) in mean point spacings."""
        triangles, _ = triangles_of(mesh)
        _, gap = nearest_triangles(points, mesh.vertices, triangles)
        distance, spacing = np.sqrt(gap), mean_spacing(points)
        on, _ = sample_surface(mesh, 4000, np.random.default_rng(0))
        back, _ = cKDTree(points).query(on)
        return distance.mean() / spacing, (distance > 2 * spacing).mean(), back.mean() / spacing

    thicknesses = [float(t) for t in args.thickness.split(",")]
    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=0)
    generator = MeshGenerator.from_repository(None, threads=1)
    for index, shape in enumerate(shapes):
        direction = DIRECTIONS[index % len(DIRECTIONS)]
        points = shape.points[one_sided(shape.normals, direction)]  # (P', 3)
        started = time.perf_counter()
        first = generator.generate(points, seed=0)
        meshes = {"default": first.mesh}
        diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
        opened = bool(first.fit and first.fit.open_surface)
        if opened:
            normals = estimate_point_normals(points)  # (P', 3) unoriented
            triangles, _ = triangles_of(first.mesh)
            owner, _ = nearest_triangles(points, first.mesh.vertices, triangles)
            corners = first.mesh.vertices[triangles[owner]]
            facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            normals *= np.where(np.sum(normals * facing, axis=1) < 0, -1.0, 1.0)[:, None]
            for t in thicknesses:
                slab = np.concatenate([points, points - t * diagonal * normals])
                closed = generator.generate(slab, seed=0, surface="closed")
                meshes[f"t{t}"], _, _ = shape_surface(closed.mesh, points, None, "open",
                                                      generator.spec.geometry)
        for name, mesh in meshes.items():
            s = scan_scores(mesh, shape.mesh, direction, seed=[0, index])
            p2m, unc, m2p = measures(mesh, points) if mesh.n_faces else (np.nan,) * 3
            print(f"{index:2d} {shape.shape_id[:28]:28s} {name:7s} open={opened!s:5s} "
                  f"acc {100 * s['accuracy']:.3f} comp {100 * s['completeness']:.3f} "
                  f"area {s['area_ratio']:.2f} valid {s['valid']} | p2m {p2m:.3f} "
                  f"unc {unc:.3f} m2p {m2p:.3f}", flush=True)
        print(f"   {time.perf_counter() - started:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
