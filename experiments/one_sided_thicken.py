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

With ``--measures``, each mesh also gets what the service could measure without the
truth: the mean distance from the points to it (``p2m``) and from it to the points
(``m2p``), in mean point spacings, and the share of points farther than two spacings
(``unc``); and the means are also given for the mesh of each scan that ``p2m + m2p``
picks (the slab as a candidate beside the default, 2026-12-08: docs/GEOMETRY.md, "Tried
on the way to the two candidates").

Usage::

    python experiments/one_sided_thicken.py --split dev [--thickness 0.02,0.05]
        [--measures]
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
    parser.add_argument("--measures", action="store_true",
                        help="also the runtime measures, and the means of their pick")
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

    def measures(mesh, points) -> tuple[float, float, float]:
        """(p2m, unc, m2p) of the module docstring, in mean point spacings."""
        if mesh.n_faces == 0:
            return np.nan, np.nan, np.nan
        triangles, _ = triangles_of(mesh)
        _, gap = nearest_triangles(points, mesh.vertices, triangles)
        distance, spacing = np.sqrt(gap), mean_spacing(points)
        on, _ = sample_surface(mesh, 4000, np.random.default_rng(0))
        back, _ = cKDTree(points).query(on)
        return (float(distance.mean() / spacing), float((distance > 2 * spacing).mean()),
                float(back.mean() / spacing))

    thicknesses = [float(t) for t in args.thickness.split(",")]
    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=args.seed)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=1)
    names = ["default", *[f"t{t}" for t in thicknesses]]
    scores: dict[str, list[tuple[float, float, float]]] = {name: [] for name in names}
    picked: list[tuple[float, float, float]] = []  # with --measures: p2m + m2p's pick
    for index, shape in enumerate(shapes):
        direction = DIRECTIONS[index % len(DIRECTIONS)]
        points = shape.points[one_sided(shape.normals, direction)]  # (P', 3)
        started = time.perf_counter()
        first = generator.generate(points, seed=args.seed)
        meshes = {"default": first.mesh}
        diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
        opened = bool(first.fit and first.fit.open_surface)
        if opened:  # the points' normals, facing like the opened output's nearest face
            normals = estimate_point_normals(points)  # (P', 3) unoriented
            triangles, _ = triangles_of(first.mesh)
            owner, _ = nearest_triangles(points, first.mesh.vertices, triangles)
            corners = first.mesh.vertices[triangles[owner]]
            facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            normals *= np.where(np.sum(normals * facing, axis=1) < 0, -1.0, 1.0)[:, None]
        for t in thicknesses:
            if not opened:
                meshes[f"t{t}"] = first.mesh
                continue
            slab = np.concatenate([points, points - t * diagonal * normals])
            closed = generator.generate(slab, seed=args.seed, surface="closed")
            trimmed, _, _ = shape_surface(closed.mesh, points, None, "open",
                                              generator.spec.geometry)
            meshes[f"t{t}"] = trimmed
        line = [f"{shape.shape_id[:40]:40s} open {opened!s:5s}"]
        proxies = {}
        for name in names:
            s = scan_scores(meshes[name], shape.mesh, direction, seed=[args.seed, index])
            scores[name].append((s["accuracy"], s["completeness"], s["area_ratio"]))
            line.append(f"{name} {s['accuracy']:.4f}/{s['completeness']:.4f}/"
                        f"{s['area_ratio']:.2f}{'' if s['valid'] else ' INVALID'}")
            if args.measures:
                p2m, unc, m2p = proxies[name] = measures(meshes[name], points)
                line[-1] += f" p2m {p2m:.3f} unc {unc:.3f} m2p {m2p:.3f}"
        if args.measures:
            pick = min(names, key=lambda n: np.nan_to_num(proxies[n][0] + proxies[n][2],
                                                          nan=np.inf))
            picked.append(scores[pick][-1])
        print(" | ".join(line), f"| {time.perf_counter() - started:.1f} s", flush=True)
    print("\nmeans (accuracy 1e-2 / completeness 1e-2 / area over seen):")
    for name in names:
        a = np.array(scores[name])
        print(f"{name:10s} {100 * np.nanmean(a[:, 0]):.2f} / {100 * np.nanmean(a[:, 1]):.2f}"
              f" / {np.nanmean(a[:, 2]):.2f}")
    if picked:
        a = np.array(picked)
        print(f"{'p2m+m2p':10s} {100 * np.nanmean(a[:, 0]):.2f} / "
              f"{100 * np.nanmean(a[:, 1]):.2f} / {np.nanmean(a[:, 2]):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
