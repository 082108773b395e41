"""Can visibility tell a one-sided scan from a complete cloud? (issue 36, ``surface=auto``)

For each closed mesh of a split (2,048 points sampled as ``eval_real_meshes.py`` does),
hidden point removal (Katz et al. 2007: spherical flipping about a viewpoint, then the
convex hull; scipy) is run from 64 viewpoints spread over a sphere three diagonals from
the points, and the largest share of points visible from any of them is printed for the
complete cloud (clean, 1% and 2% noise, 5% outliers with the pipeline's outlier test
applied) and for its six one-sided scans (the points whose true normal has a positive
component along an axis direction) and one of them with 1% noise. A one-sided scan is
seen whole from its side; a closed surface about half. ``--radius`` is the flipping
sphere's radius over the farthest point's distance (larger: more points visible).

Usage::

    python experiments/visibility_one_sided.py --split dev [--radius 100,1000] [--limit N]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser

AXES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float)


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--radius", default="100,1000")
    parser.add_argument("--limit", type=int, default=None)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import corrupt_points, mesh_shapes
    from spacemesh.geometry.cleaning import find_outliers
    from spacemesh.metrics.scans import one_sided

    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=0)[: args.limit]
    radii = [float(r) for r in args.radius.split(",")]
    for radius in radii:
        print(f"\nradius {radius:g}: the largest share visible from one viewpoint")
        print("shape | clean | 1% | 2% | 5% outliers | one-sided (6 axes) | one-sided, 1%")
        complete, scans = [], []
        for index, shape in enumerate(shapes):
            row = []
            for noise, outliers in ((0.0, 0.0), (0.01, 0.0), (0.02, 0.0), (0.0, 0.05)):
                points = corrupt_points(shape.points, noise=noise, outliers=outliers,
                                        seed=[0, index])
                if outliers:
                    points = points[~find_outliers(points)]
                row.append(best_view_share(points, radius))
            assert shape.normals is not None
            sided = [best_view_share(shape.points[one_sided(shape.normals, axis)], radius)
                     for axis in AXES]
            noisy = corrupt_points(shape.points[one_sided(shape.normals, AXES[index % 6])],
                                   noise=0.01, seed=[0, index])
            sided_noisy = best_view_share(noisy, radius)
            complete.append(row)
            scans.append([*sided, sided_noisy])
            print(f"{shape.shape_id[:40]} | " + " | ".join(f"{v:.2f}" for v in row)
                  + " | " + " ".join(f"{v:.2f}" for v in sided) + f" | {sided_noisy:.2f}")
        c, s = np.array(complete), np.array(scans)
        print(f"complete clean: max {c[:, 0].max():.2f}; complete, any: max {c.max():.2f}; "
              f"one-sided clean: min {s[:, :6].min():.2f}; one-sided 1%: min "
              f"{s[:, 6].min():.2f}")
    return 0


def fibonacci_sphere(count: int) -> np.ndarray:
    """``(count, 3)`` unit vectors spread evenly over the sphere."""
    i = np.arange(count) + 0.5
    polar, turn = np.arccos(1 - 2 * i / count), np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar),
                     np.cos(polar)], axis=1)


def best_view_share(points: np.ndarray, radius: float, views: int = 64) -> float:
    """The largest share of ``points`` that hidden point removal keeps visible from
    viewpoints three diagonals from their centre (``radius``: the flipping sphere's
    radius over the farthest point's distance)."""
    centre = points.mean(axis=0)
    extent = float(np.linalg.norm(np.ptp(points, axis=0)))
    best = 0.0
    for direction in fibonacci_sphere(views):
        rel = points - (centre + 3.0 * extent * direction)  # (P, 3)
        norm = np.linalg.norm(rel, axis=1)
        flipped = rel + 2.0 * (radius * norm.max() - norm)[:, None] * rel / norm[:, None]
        hull = ConvexHull(np.vstack([flipped, np.zeros((1, 3))]))
        visible = np.count_nonzero(hull.vertices < len(points))
        best = max(best, visible / len(points))
    return best


if __name__ == "__main__":
    raise SystemExit(main())
