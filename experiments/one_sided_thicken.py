"""Trial (issue 36): a one-sided scan decoded as a thin slab, then trimmed to its points.

The closed decode of a one-sided sheet of points collapses (a flat face seen square-on
comes back as a tenth of its area) or folds (a thin tray). Trial: where ``surface=auto``
opened the default output, the points get a copy pushed back by ``--thickness`` of the
diagonal along their normals (estimated from the points, oriented like the nearest face
of the opened output, which faces the side the points were seen from), the slab is
decoded closed, and the result trimmed to the *original* points and fitted to them
(:func:`spacemesh.geometry.surface.shape_surface` with ``open``). Scored as
``experiments/eval_one_sided.py`` scores (accuracy, completeness of the seen part, area
over the seen area), default against each thickness.

Usage::

    python experiments/one_sided_thicken.py --split dev [--thickness 0.02,0.05]
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
    parser.add_argument("--thickness", default="0.02,0.05")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import mesh_shapes, pin_threads

    pin_threads(1)
    from spacemesh.geometry.fitting import estimate_point_normals
    from spacemesh.geometry.surface import shape_surface
    from spacemesh.metrics.scans import one_sided, scan_scores
    from spacemesh.primitives import triangles_of
    from spacemesh.primitives.closest import nearest_triangles
    from spacemesh.runtime import MeshGenerator

    thicknesses = [float(t) for t in args.thickness.split(",")]
    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=args.seed)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=1)
    names = ["default", *[f"t{t}" for t in thicknesses]]
    scores: dict[str, list[tuple[float, float, float]]] = {name: [] for name in names}
    for index, shape in enumerate(shapes):
        direction = DIRECTIONS[index % len(DIRECTIONS)]
        points = shape.points[one_sided(shape.normals, direction)]  # (P', 3)
        started = time.perf_counter()
        first = generator.generate(points, seed=args.seed)
        meshes = {"default": first.mesh}
        diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
        opened = bool(first.fit and first.fit.open_surface)
        for t in thicknesses:
            if not opened:
                meshes[f"t{t}"] = first.mesh
                continue
            normals = estimate_point_normals(points)  # (P', 3) unoriented
            triangles, _ = triangles_of(first.mesh)
            owner, _ = nearest_triangles(points, first.mesh.vertices, triangles)
            corners = first.mesh.vertices[triangles[owner]]
            facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            normals *= np.where(np.sum(normals * facing, axis=1) < 0, -1.0, 1.0)[:, None]
            slab = np.concatenate([points, points - t * diagonal * normals])
            closed = generator.generate(slab, seed=args.seed, surface="closed")
            trimmed, _, _ = shape_surface(closed.mesh, points, None, "open",
                                              generator.spec.geometry)
            meshes[f"t{t}"] = trimmed
        line = [f"{shape.shape_id[:40]:40s} open {opened!s:5s}"]
        for name in names:
            s = scan_scores(meshes[name], shape.mesh, direction, seed=[args.seed, index])
            scores[name].append((s["accuracy"], s["completeness"], s["area_ratio"]))
            line.append(f"{name} {s['accuracy']:.4f}/{s['completeness']:.4f}/"
                        f"{s['area_ratio']:.2f}{'' if s['valid'] else ' INVALID'}")
        print(" | ".join(line), f"| {time.perf_counter() - started:.1f} s", flush=True)
    print("\nmeans (accuracy 1e-2 / completeness 1e-2 / area over seen):")
    for name in names:
        a = np.array(scores[name])
        print(f"{name:10s} {100 * np.nanmean(a[:, 0]):.2f} / {100 * np.nanmean(a[:, 1]):.2f}"
              f" / {np.nanmean(a[:, 2]):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
