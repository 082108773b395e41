"""Where noise costs: the decode of noisy points, or the fit to them? (issue 36)

For every dev mesh (2,048 points as ``experiments/eval_real_meshes.py`` samples them, 1%
Gaussian noise as it adds it), the raw decode at 200 vertices of the clean and of the
noisy points is each fitted (:func:`spacemesh.geometry.finishing.finish_geometry`) to
the clean and to the noisy points; the script prints the four CDs per mesh and their
means and medians. No retry seeds, no dense decode, no untangling.

Usage::

    python experiments/noise_decode_or_fit.py [--noise 0.01] [--split dev]
"""

from __future__ import annotations

import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--noise", type=float, default=0.01)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from spacemesh.evaluate.runner import corrupt_points, mesh_shapes
    from spacemesh.geometry.finishing import finish_geometry
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.metrics.sampling import apply_normalisation, normalisation
    from spacemesh.runtime import MeshGenerator

    paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=0)
    generator = MeshGenerator.from_repository(None, threads=1)
    cds: dict[str, list[float]] = {}
    for index, shape in enumerate(shapes):
        centre, scale = normalisation(shape.mesh)
        truth = apply_normalisation(shape.mesh, centre, scale)
        clean = (np.asarray(shape.points, np.float64) - centre) / scale
        noisy = corrupt_points(clean, noise=args.noise, seed=[0, index])
        reference = Reference.from_mesh(truth, seed=[0, index, 0])
        line = [shape.shape_id[:28]]
        for decoded, decode_points in (("clean", clean), ("noisy", noisy)):
            raw = generator.generate(decode_points, None, seed=0, raw=True,
                                     target_vertices=200).mesh
            for fitted, fit_points in (("clean", clean), ("noisy", noisy)):
                mesh, _ = finish_geometry(raw, fit_points, None, generator.spec.geometry,
                                          target_vertices=200)
                cd = float(score_mesh(mesh, reference)["cd"]) * 1e3
                cds.setdefault(f"decode {decoded}, fit {fitted}", []).append(cd)
                line.append(f"{decoded}/{fitted} {cd:.3f}")
        print(" | ".join(line), flush=True)
    for name, values in cds.items():
        print(f"{name}: CD mean {statistics.mean(values):.3f}, "
              f"median {statistics.median(values):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
