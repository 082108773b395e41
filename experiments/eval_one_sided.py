"""One-sided scans of the real meshes: ours at the defaults against screened Poisson.

Each closed mesh of a split of ../shared/meshes (``experiments/real_meshes_split.csv``)
is normalised and 2048 points are sampled on it (as ``eval_real_meshes.py`` does); a
one-sided scan keeps the points whose true normal has a positive component along one
direction (the six axis directions in turn, by the mesh's position). Ours gets the bare
points at the defaults (``surface=auto``); the baseline is screened Poisson from normals
estimated from the points, decimated to our vertex count and trimmed to the points
(:func:`spacemesh.metrics.scans.trim_to_points`). Both are scored by
:func:`spacemesh.metrics.scans.scan_scores` (accuracy, completeness of the seen part,
area over the seen area, open, valid), and the shares of crossing faces by
:func:`spacemesh.geometry.intersections.self_intersection_fraction`.

With ``--complete``, the clouds are whole instead (clean, 1% and 2% noise, 5% outliers),
and the script counts the outputs ``surface=auto`` opened: complete clouds should come
back closed.

Usage::

    python experiments/eval_one_sided.py --split test [--out docs/results/one-sided]
        [--surface auto] [--limit N] [--complete]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))
DIRECTIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]],
                      dtype=np.float64)
KEYS = ("accuracy", "completeness", "area_ratio", "open", "valid", "crossing", "seconds")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument("--split", choices=("dev", "test", "all"), default="test")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "one-sided")
    parser.add_argument("--surface", default="auto")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--complete", action="store_true",
                        help="whole clouds (clean, noisy, outliers): count the open outputs")
    args = parser.parse_args()
    if not (args.meshes / "manifest.csv").is_file():
        print(f"skipped: {args.meshes / 'manifest.csv'} not found")
        return 0
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from eval_real_meshes import CATEGORIES, split_meshes

    from spacemesh.baselines import estimate_normals, psr_star, screened_poisson
    from spacemesh.evaluate.runner import mesh_shapes
    from spacemesh.geometry.intersections import self_intersection_fraction
    from spacemesh.metrics.scans import one_sided, scan_scores, trim_to_points
    from spacemesh.runtime import MeshGenerator

    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=args.seed)[: args.limit]
    generator = MeshGenerator.from_repository(args.model, threads=1)
    if args.complete:
        return complete_clouds(shapes, generator, args)
    rows = []
    for index, shape in enumerate(shapes):
        direction = DIRECTIONS[index % len(DIRECTIONS)]
        assert shape.normals is not None
        points = shape.points[one_sided(shape.normals, direction)]  # (P', 3)
        started = time.perf_counter()
        ours = generator.generate(points, surface=args.surface, seed=args.seed)
        ours_seconds = time.perf_counter() - started
        started = time.perf_counter()
        poisson = screened_poisson(points, estimate_normals(points))
        baseline = trim_to_points(psr_star(poisson, ours.mesh.n_vertices), points)
        psr_seconds = time.perf_counter() - started
        for method, mesh, seconds in (("ours", ours.mesh, ours_seconds),
                                      ("psr_star_trimmed", baseline, psr_seconds)):
            row = {"shape_id": shape.shape_id, "category": shape.category, "method": method,
                   "direction": direction.tolist(), "seconds": seconds,
                   "n_vertices": mesh.n_vertices,
                   **scan_scores(mesh, shape.mesh, direction, seed=[args.seed, index]),
                   "crossing": self_intersection_fraction(mesh) if mesh.n_faces else 0.0}
            if method == "ours":
                row["unsupported_area"] = ours.fit.unsupported_area if ours.fit else None
            rows.append(row)
            print(f"{shape.shape_id[:44]:44s} {method:17s} acc {row['accuracy']:.4f} "
                  f"comp {row['completeness']:.4f} area {row['area_ratio']:.2f} "
                  f"open {row['open']} valid {row['valid']} cross {row['crossing']:.3f}",
                  flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.split}.json").write_text(json.dumps(rows, indent=1))
    table = summary_table(rows, args)
    (args.out / f"{args.split}.md").write_text(table)
    print(table)
    return 0


def complete_clouds(shapes: list, generator: object, args: argparse.Namespace) -> int:
    """Whole clouds, clean and corrupted: the share of outputs ``surface=auto`` opened."""
    from spacemesh.evaluate.runner import corrupt_points

    lines = [f"# surface={args.surface} on complete clouds, {args.split} split "
             f"({len(shapes)} meshes)\n",
             f"Rebuild: `python experiments/eval_one_sided.py --split {args.split} --complete`\n",
             "| points | open outputs | mean unsupported area | largest |", "|---|---|---|---|"]
    for name, noise, outliers in (("clean", 0.0, 0.0), ("1% noise", 0.01, 0.0),
                                  ("2% noise", 0.02, 0.0), ("5% outliers", 0.0, 0.05)):
        opened, shares = [], []
        for index, shape in enumerate(shapes):
            points = corrupt_points(shape.points, noise=noise, outliers=outliers,
                                    seed=[args.seed, index])
            fit = generator.generate(points, surface=args.surface, seed=args.seed).fit  # type: ignore[attr-defined]
            opened.append(bool(fit.open_surface))
            shares.append(float(fit.unsupported_area))
            if fit.open_surface:
                print(f"{name}: {shape.shape_id} opened ({fit.unsupported_area:.2f})",
                      flush=True)
        lines.append(f"| {name} | {sum(opened)} of {len(opened)} | {np.mean(shares):.3f} "
                     f"| {max(shares):.3f} |")
        print(lines[-1], flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.split}-complete.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def summary_table(rows: list[dict], args: argparse.Namespace) -> str:
    """Means over the set, one line per method."""
    lines = [f"# One-sided scans, {args.split} split ({len(rows) // 2} meshes)\n",
             f"Rebuild: `python experiments/eval_one_sided.py --split {args.split}`; "
             f"ours at `surface={args.surface}`, bare points.\n",
             "| method | accuracy 1e-2 ↓ | completeness 1e-2 ↓ | area / seen | open % "
             "| valid % | crossing faces % | s |",
             "|---|---|---|---|---|---|---|---|"]
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        mean = {k: float(np.nanmean([float(r[k]) for r in mine])) for k in KEYS}
        lines.append(f"| {method} | {100 * mean['accuracy']:.2f} "
                     f"| {100 * mean['completeness']:.2f} | {mean['area_ratio']:.2f} "
                     f"| {100 * mean['open']:.0f} | {100 * mean['valid']:.0f} "
                     f"| {100 * mean['crossing']:.2f} | {mean['seconds']:.2f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
