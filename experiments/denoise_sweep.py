"""How far noisy points lie from the true surface before and after the denoising.

The denoising was tried and dropped (docs/GEOMETRY.md, "Tried and dropped: denoising
the points"): ``git apply experiments/patches/denoise_points.diff`` (on d4a8b3d) first,
which adds ``spacemesh.geometry.denoise``. A quick stand-in for the full evaluation while
tuning :func:`spacemesh.geometry.denoise.denoise_points`: on every mesh of one split of the
real meshes (2,048 points, as ``experiments/eval_real_meshes.py`` samples them, with
the same noise), the outliers are set aside and the noise measured as the pipeline does
(:func:`spacemesh.geometry.cleaning.assess_points`), each variant moves the points, and
the script prints the points' mean and 90th-percentile distance to the true surface (a
fraction of the bounding-box diagonal) with and without it. Tune on ``dev`` only.

Usage::

    python experiments/denoise_sweep.py --split dev --noise 0,0.01,0.02 \\
        --variant 'shipped={}' --variant 'k16={"neighbours": 16}'
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))

from eval_real_meshes import CATEGORIES, split_meshes  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parents[1] / "shared" / "meshes")
    parser.add_argument("--split", choices=("dev", "test"), default="dev")
    parser.add_argument("--noise", default="0,0.01,0.02")
    parser.add_argument("--variant", action="append",
                        help="name=JSON of denoise_points keyword arguments")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--per-shape", action="store_true")
    args = parser.parse_args()

    from spacemesh.evaluate.runner import corrupt_points, mesh_shapes
    from spacemesh.geometry.cleaning import assess_points
    from spacemesh.geometry.denoise import denoise_points
    from spacemesh.primitives.triangles import triangles_of

    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories)[: args.limit]
    variants = [(name, json.loads(text)) for name, text in
                (v.split("=", 1) for v in (args.variant or ["shipped={}"]))]
    for noise in (float(n) for n in args.noise.split(",")):
        rows: dict[str, list[tuple[float, float, float]]] = {"none": []}
        touched = {name: 0 for name, _ in variants}
        for index, shape in enumerate(shapes):
            points = corrupt_points(shape.points, noise=noise, seed=[0, index])
            quality = assess_points(points)
            points = points[quality.kept]
            truth = (shape.mesh.vertices, triangles_of(shape.mesh)[0],
                     float(np.linalg.norm(np.ptp(shape.points, axis=0))))
            rows["none"].append((*_distance(points, *truth), quality.noise))
            for name, keywords in variants:
                moved = denoise_points(points, quality.noise, **keywords)
                touched[name] += moved is not points
                rows.setdefault(name, []).append((*_distance(moved, *truth), quality.noise))
            if args.per_shape:
                print(f"  {noise:g} {shape.shape_id[:40]:40s} noise {quality.noise:.4f} "
                      + " ".join(f"{name} {values[-1][0]:.5f}" for name, values in rows.items()))
        print(f"noise {noise:g} ({len(shapes)} shapes): mean / p90 distance to the surface "
              "(% of the diagonal), measured noise median (%)")
        for name, values in rows.items():
            table = np.array(values)  # (S, 3)
            count = f", {touched[name]} clouds moved" if name in touched else ""
            print(f"  {name:24s} {100 * table[:, 0].mean():.3f} / {100 * table[:, 1].mean():.3f}"
                  f"  (noise {100 * np.median(table[:, 2]):.2f}, max "
                  f"{100 * table[:, 2].max():.2f}{count})")
    return 0


def _distance(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
              diagonal: float) -> tuple[float, float]:
    """Mean and 90th-percentile distance of ``points`` to the triangles, over ``diagonal``."""
    from spacemesh.primitives.closest import nearest_triangles

    _, gap = nearest_triangles(points, vertices, triangles)
    far = np.sqrt(gap) / diagonal  # (P,)
    return float(far.mean()), float(np.percentile(far, 90))


if __name__ == "__main__":
    sys.exit(main())
