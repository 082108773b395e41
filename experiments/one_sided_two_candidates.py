"""Trial (issue 36): an open surface trimmed after the geometry stage, before it, or the
better of the two (what ships), on one-sided scans of the real meshes.

Three runs of the pipeline per scan (seed 0, bare points, ``surface=auto``):

* ``after``: the chosen seed's closed mesh fitted, then trimmed to the points (the only
  candidate before 2026-12-08; ``MeshGenerator._trimmed_first`` switched off);
* ``first``: every seed's decode trimmed to the points before the geometry stage, then
  fitted (where ``auto`` opens the decode itself);
* ``shipped``: the better of the two for the chosen seed (no crossing, then the fit
  score; :meth:`spacemesh.runtime.MeshGenerator._trimmed_first`).

Each is scored as ``experiments/eval_one_sided.py`` scores (accuracy, completeness of the
seen part, area over the seen area, in 1e-2 of the diagonal), with the fit score
(:func:`spacemesh.geometry.report.fit_score`, x 1e3) the choice reads.

With ``--gallery PATH`` the listed scans (``--show``, indices into the split) are drawn:
their points, the three meshes and the ground truth's seen part.

Usage::

    python experiments/one_sided_two_candidates.py --split dev [--limit N]
        [--gallery docs/results/one-sided-two-candidates.png --show 2,10,15,20]
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))


def main() -> int:
    from eval_one_sided import DIRECTIONS
    from eval_real_meshes import CATEGORIES, split_meshes, split_parser

    parser = split_parser(__doc__)
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--gallery", type=Path, default=None)
    parser.add_argument("--show", default="", help="comma-separated shape indices")
    args = parser.parse_args()
    show = [int(i) for i in args.show.split(",") if i]
    from spacemesh.evaluate.runner import mesh_shapes, pin_threads

    pin_threads(1)
    import spacemesh.runtime.network as network
    from spacemesh.evaluate.gallery import GalleryRow, render_gallery
    from spacemesh.geometry.finishing import fit_trimmed_first
    from spacemesh.geometry.report import SurfaceFacts, fit_score
    from spacemesh.geometry.surface import decide_open, face_support
    from spacemesh.metrics.scans import one_sided, scan_scores, seen_faces
    from spacemesh.primitives import faces_subset
    from spacemesh.runtime import MeshGenerator

    shipped_finish, shipped_surface = network.finish_geometry, network.shape_surface
    decided: dict[str, SurfaceFacts] = {}

    def finish_first(mesh, unit, normals, options, **targets):
        """The geometry stage of a decode that ``auto`` opens: trimmed first."""
        support = face_support(mesh, unit, normals)
        decided["facts"] = SurfaceFacts(decide_open("auto", support), support.unsupported_area)
        made = fit_trimmed_first(mesh, unit, normals, options, **targets)
        if decided["facts"].open and made is not None:
            return made
        decided["facts"] = replace(decided["facts"], open=False)
        return shipped_finish(mesh, unit, normals, options, **targets)

    def surface_first(mesh, unit, normals, mode, options):
        if decided["facts"].open:
            return mesh, decided["facts"], {}
        return shipped_surface(mesh, unit, normals, mode, options)

    shipped_choice = MeshGenerator._trimmed_first
    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=0)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=1)
    names = ("after", "first", "shipped")
    scores: dict[str, list[tuple[float, float, float, float]]] = {name: [] for name in names}
    rows: list[GalleryRow] = []
    for index, shape in enumerate(shapes):
        if show and args.gallery is not None and index not in show:
            continue
        direction = DIRECTIONS[index % len(DIRECTIONS)]
        points = shape.points[one_sided(shape.normals, direction)]  # (P', 3)
        started = time.perf_counter()
        meshes = {}
        MeshGenerator._trimmed_first = lambda self, chosen, *rest: chosen  # type: ignore[method-assign]
        meshes["after"] = generator.generate(points, seed=0).mesh
        network.finish_geometry, network.shape_surface = finish_first, surface_first
        meshes["first"] = generator.generate(points, seed=0).mesh
        network.finish_geometry, network.shape_surface = shipped_finish, shipped_surface
        MeshGenerator._trimmed_first = shipped_choice  # type: ignore[method-assign]
        meshes["shipped"] = generator.generate(points, seed=0).mesh
        line = [f"{shape.shape_id[:36]:36s}"]
        for name in names:
            s = scan_scores(meshes[name], shape.mesh, direction, seed=[0, index])
            fit = 1e3 * fit_score(meshes[name], points)
            scores[name].append((s["accuracy"], s["completeness"], s["area_ratio"], fit))
            line.append(f"{name} {100 * s['accuracy']:.3f}/{100 * s['completeness']:.3f}/"
                        f"{s['area_ratio']:.2f} fit {fit:.1f}"
                        f"{'' if s['valid'] else ' INVALID'}")
        print(" | ".join(line), f"| {time.perf_counter() - started:.1f} s", flush=True)
        if index in show:
            seen, _ = faces_subset(shape.mesh, seen_faces(shape.mesh, direction)
                                   ).remove_unreferenced_vertices()
            rows.append(GalleryRow(f"{shape.shape_id} from {direction.astype(int).tolist()}",
                                   points, {**meshes, "gt": seen}))
    print("\nmeans (accuracy 1e-2 / completeness 1e-2 / area over seen / fit score 1e-3):")
    for name in names:
        a = np.array(scores[name])
        print(f"{name:8s} {100 * np.nanmean(a[:, 0]):.2f} / {100 * np.nanmean(a[:, 1]):.2f}"
              f" / {np.nanmean(a[:, 2]):.2f} / {np.nanmean(a[:, 3]):.1f}")
    if args.gallery is not None and rows:
        render_gallery(rows, args.gallery, columns=("points", *names, "gt"),
                       labels={"after": "trimmed after the fit", "first": "trimmed first",
                               "shipped": "the better (ships)", "gt": "seen part"},
                       title="One-sided scans: two candidates")
        print(f"gallery: {args.gallery}")
    a = np.array([min((scores[n][i] for n in ("after", "first")), key=lambda r: r[3])
                  for i in range(len(scores["after"]))])
    print(f"{'by fit':8s} {100 * a[:, 0].mean():.2f} / {100 * a[:, 1].mean():.2f}"
          f" / {a[:, 2].mean():.2f} / {a[:, 3].mean():.1f}  (the better fit of after and first)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
