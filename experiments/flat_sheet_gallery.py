"""Flat sheets of points with and without their slab (docs/GEOMETRY.md, "Open surfaces").

For random squares of points (375 on 2 x 2, as many as a face of a 2,048-point cube
gets) and the one-sided scans of a split whose points form a flat sheet
(:data:`spacemesh.geometry.sheet.FLAT_SHEET`), the default pipeline (bare points,
``surface=auto``) runs twice: as it ships, and with the slab candidate switched off
(``MeshGenerator._flat_slab`` returning the chosen mesh). Prints the pieces, the area,
the share of points within reach (the fit report's ``coverage``) and the time of each,
and draws them with ``--gallery``.

Usage::

    python experiments/flat_sheet_gallery.py --split dev [--squares 2]
        [--gallery docs/geometry/flat_sheet_slab.png]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> int:
    from eval_one_sided import DIRECTIONS
    from eval_real_meshes import CATEGORIES, split_meshes, split_parser

    parser = split_parser(__doc__)
    parser.add_argument("--squares", type=int, default=2)
    parser.add_argument("--gallery", type=Path, default=None)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import mesh_shapes, pin_threads

    pin_threads(1)
    from spacemesh.evaluate.gallery import GalleryRow, render_gallery
    from spacemesh.geometry.cleaning import find_outliers
    from spacemesh.geometry.sheet import FLAT_SHEET, sheet_plane
    from spacemesh.metrics.scans import one_sided
    from spacemesh.runtime import MeshGenerator

    inputs = []
    for seed in range(args.squares):
        rng = np.random.default_rng(seed)
        inputs.append((f"square {seed}", np.c_[rng.uniform(-1, 1, (375, 2)), np.zeros(375)]))
    if (args.meshes / "manifest.csv").is_file():
        paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
        for index, shape in enumerate(mesh_shapes(paths, categories=categories, seed=0)):
            direction = DIRECTIONS[index % len(DIRECTIONS)]
            assert shape.normals is not None
            points = shape.points[one_sided(shape.normals, direction)]  # (P', 3)
            if sheet_plane(points[~find_outliers(points)])[1] <= FLAT_SHEET:
                inputs.append((f"{shape.shape_id[:32]} from "
                               f"{direction.astype(int).tolist()}", points))
    generator = MeshGenerator.from_repository(None, threads=1)
    shipped = MeshGenerator._flat_slab
    rows = []
    for name, points in inputs:
        meshes = {}
        line = [f"{name:48s}"]
        for label, slab in (("without", False), ("with", True)):
            MeshGenerator._flat_slab = shipped if slab else (  # type: ignore[method-assign]
                lambda self, chosen, *rest: chosen)
            started = time.perf_counter()
            result = generator.generate(points, seed=0)
            seconds = time.perf_counter() - started
            fit = result.fit
            assert fit is not None
            meshes[f"{label} the slab"] = result.mesh
            line.append(f"{label}: {result.mesh.n_vertices} vertices, {fit.pieces} pieces, "
                        f"area {_area(result.mesh):.2f}, coverage {fit.coverage:.3f}, "
                        f"{seconds:.1f} s")
        MeshGenerator._flat_slab = shipped  # type: ignore[method-assign]
        print(" | ".join(line), flush=True)
        rows.append(GalleryRow(name, points, meshes))
    if args.gallery is not None and rows:
        render_gallery(rows, args.gallery,
                       columns=("points", "without the slab", "with the slab"),
                       title="Flat sheets of points: decoded alone, and as a slab")
        print(f"gallery: {args.gallery}")
    return 0


def _area(mesh) -> float:
    """Total area of ``mesh``'s faces (fan triangles)."""
    from spacemesh.primitives import triangles_of

    triangles, _ = triangles_of(mesh)
    corners = mesh.vertices[triangles]  # (T, 3, 3)
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return float(0.5 * np.linalg.norm(cross, axis=1).sum())


if __name__ == "__main__":
    raise SystemExit(main())
