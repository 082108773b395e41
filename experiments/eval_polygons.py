"""Issue 35: ``face_type=polygons`` against ``face_type=triangles`` on real meshes.

For each mesh of a split (bare xyz points sampled from it, seed 0, every other option
at its default), the shipped model generates with ``face_type=triangles`` and with
``face_type=polygons``; per shape it prints the faces of each and their ratio, the
vertices, the CD of each (1e-3, normalised frame), the polygons' worst planarity (the fit
report's ``face_planarity``, a fraction of the diagonal), the share of crossing faces
(the fit report's ``self_intersections``), whether each mesh is a valid (closed unless
declared open) oriented manifold, and the time of each; then the means. The bar
(issue 35, CAD-like parts): ratio at most 0.6, CD ratio at most 1.1, planarity at most
0.001, no crossing faces, valid.

Usage::

    python experiments/eval_polygons.py --split dev [--category cad] [--limit N]

``--category cad`` keeps the CAD-like categories (``cad``, ``cad-abc``,
``polygon-cad``); ``--category other`` the rest; a category's own name keeps it alone.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))

#: The CAD-like categories (issue 35's bar is for these).
CAD_LIKE = ("cad", "cad-abc", "polygon-cad")


def _wanted(category: str, every: tuple[str, ...]) -> set[str]:
    if category == "all":
        return set(every)
    if category == "cad":
        return set(CAD_LIKE)
    if category == "other":
        return set(every) - set(CAD_LIKE)
    return {category}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("dev", "test", "all"), default="dev")
    parser.add_argument("--category", default="all",
                        help="cad (the CAD-like ones), other, all, or one category")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--data", type=Path, default=None,
                        help="a shard dataset (e.g. data/qemflip-heldout-s2) instead of "
                             "the real meshes: its --split test shapes, every one CAD-like")
    parser.add_argument("--out", type=Path, default=Path("/tmp/eval_polygons.csv"))
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from eval_real_meshes import CATEGORIES, split_meshes

    from spacemesh.evaluate.runner import dataset_shapes, mesh_shapes
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.metrics.sampling import apply_normalisation, normalisation
    from spacemesh.runtime import MeshGenerator

    if args.data is not None:  # a synthetic set: every shape counts as CAD-like
        shapes = [replace(shape, category="cad") for shape in dataset_shapes(
            args.data, "all" if args.split == "all" else "test", args.limit)]
    else:
        paths, categories = split_meshes(ROOT.parent / "shared" / "meshes", args.split,
                                         _wanted(args.category, CATEGORIES))
        shapes = mesh_shapes(paths, categories=categories, seed=0)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=1)
    rows = []
    print(f"{'shape':34s} {'cat':11s} {'F tri':>5s} {'F poly':>6s} {'ratio':>5s} "
          f"{'V tri':>5s} {'V poly':>6s} {'CD tri':>6s} {'CD poly':>7s} {'plan%':>6s} "
          f"{'cross':>5s} {'valid':>5s} {'s tri':>5s} {'s poly':>6s}")
    for index, shape in enumerate(shapes):
        centre, scale = normalisation(shape.mesh)
        gt = apply_normalisation(shape.mesh, centre, scale)
        points = (np.asarray(shape.points, np.float64) - centre) / scale
        reference = Reference.from_mesh(gt, seed=[0, index, 0])
        row: dict[str, object] = {"shape": shape.shape_id, "category": shape.category}
        for kind in ("triangles", "polygons"):
            started = time.perf_counter()
            result = generator.generate(points, None, seed=0, face_type=kind)
            seconds = time.perf_counter() - started
            fit = result.fit
            assert fit is not None
            score = score_mesh(result.mesh, reference, open_surface=bool(fit.open_surface))
            tag = kind[:4]
            row.update({f"faces_{tag}": result.mesh.n_faces,
                        f"vertices_{tag}": result.mesh.n_vertices,
                        f"cd_{tag}": score["cd"], f"valid_{tag}": bool(score["valid"]),
                        f"planarity_{tag}": fit.face_planarity,
                        f"crossing_{tag}": fit.self_intersections, f"s_{tag}": seconds})
        row["ratio"] = row["faces_poly"] / row["faces_tria"]  # type: ignore[operator]
        rows.append(row)
        print(f"{shape.shape_id[:34]:34s} {shape.category[:11]:11s} "
              f"{row['faces_tria']:5d} {row['faces_poly']:6d} {row['ratio']:5.2f} "
              f"{row['vertices_tria']:5d} {row['vertices_poly']:6d} "
              f"{row['cd_tria'] * 1e3:6.3f} {row['cd_poly'] * 1e3:7.3f} "
              f"{row['planarity_poly'] * 100:6.3f} {row['crossing_poly']:5.3f} "
              f"{int(row['valid_tria'])}/{int(row['valid_poly'])}   "
              f"{row['s_tria']:5.1f} {row['s_poly']:6.1f}", flush=True)
    _summary(rows, "all")
    cad = [r for r in rows if r["category"] in CAD_LIKE]
    if cad and len(cad) < len(rows):
        _summary(cad, "CAD-like")
        _summary([r for r in rows if r["category"] not in CAD_LIKE], "other")
    with args.out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {args.out}")
    return 0


def _summary(rows: list[dict[str, object]], name: str) -> None:
    def mean(key: str) -> float:
        return float(np.mean([float(r[key]) for r in rows]))  # type: ignore[arg-type]

    ratios = [float(r["ratio"]) for r in rows]  # type: ignore[arg-type]
    cd_ratio = mean("cd_poly") / mean("cd_tria")
    print(f"{name} ({len(rows)}): faces {mean('faces_tria'):.0f} -> {mean('faces_poly'):.0f}, "
          f"ratio mean {np.mean(ratios):.3f} (min {min(ratios):.2f}, max {max(ratios):.2f}); "
          f"vertices {mean('vertices_tria'):.0f} -> {mean('vertices_poly'):.0f}; "
          f"CD {mean('cd_tria') * 1e3:.3f} -> {mean('cd_poly') * 1e3:.3f} (x{cd_ratio:.3f}); "
          f"worst planarity {max(float(r['planarity_poly']) for r in rows) * 100:.3f}%; "  # type: ignore[arg-type]
          f"crossing shapes {sum(float(r['crossing_poly']) > 0 for r in rows)}; "  # type: ignore[arg-type]
          f"invalid {sum(not r['valid_poly'] for r in rows)}; "
          f"time {np.median([float(r['s_tria']) for r in rows]):.2f} -> "  # type: ignore[arg-type]
          f"{np.median([float(r['s_poly']) for r in rows]):.2f} s median", flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
