"""Sweep the geometry stage and the vertex start on one split of the real meshes.

Each variant changes fields of the shipped model's :class:`~spacemesh.runtime.ModelSpec`
(``start_time``, ``feature_boost``, ``vertices``) and of its geometry stage
(:class:`~spacemesh.geometry.GeometryOptions`; ``fit`` takes
:class:`~spacemesh.geometry.VertexFitOptions` fields), runs the pipeline on every mesh of the
split (the same points and metric seeds as ``experiments/eval_real_meshes.py``) and
prints mean CD, median CD, ECD, EF1, IN and self-intersections. Tune on ``dev`` only
(docs/GEOMETRY.md has the tables this made).

Usage::

    python experiments/geometry_sweep.py --split dev \\
        --variant 'shipped={}' \\
        --variant 'no_planes={"geometry": {"fit": {"plane_weight": 0}}}' \\
        --variant 'start_time_0.1={"start_time": 0.1}'
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _spec_with(spec, changes: dict):
    geometry = dict(changes.get("geometry", {}))
    fit = replace(spec.geometry.fit, **geometry.pop("fit", {}))
    others = {k: v for k, v in changes.items() if k != "geometry"}
    return replace(spec, geometry=replace(spec.geometry, fit=fit, **geometry), **others)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument("--split", choices=("dev", "test"), default="dev")
    parser.add_argument("--model", default=None)
    parser.add_argument("--noise", type=float, default=0.0,
                        help="Gaussian noise on the points (fraction of the diagonal)")
    parser.add_argument("--variant", action="append", default=[],
                        help="NAME=JSON of spec / geometry changes (repeatable)")
    args = parser.parse_args()
    if not (args.meshes / "manifest.csv").is_file():
        print(f"skipped: {args.meshes} not found")
        return 0
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    from spacemesh.evaluate.runner import corrupt_points, mesh_shapes
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.metrics.sampling import apply_normalisation, normalisation
    from spacemesh.runtime import MeshGenerator

    with (ROOT / "experiments" / "real_meshes_split.csv").open() as handle:
        rows = [r for r in csv.DictReader(handle) if r["split"] == args.split]
    rows.sort(key=lambda r: (r["category"], int(r["n_vertices"])))
    shapes = mesh_shapes([args.meshes / r["file"] for r in rows],
                         categories=[r["category"] for r in rows], seed=0)
    generator = MeshGenerator.from_repository(args.model, threads=1)
    prepared = []
    for index, shape in enumerate(shapes):
        centre, scale = normalisation(shape.mesh)
        truth = apply_normalisation(shape.mesh, centre, scale)
        points = corrupt_points((shape.points - centre) / scale, noise=args.noise,
                                seed=[0, index])
        prepared.append((points, Reference.from_mesh(truth, seed=[0, index, 0])))
    shipped = generator.spec
    variants = [v.split("=", 1) for v in (args.variant or ["shipped={}"])]
    for name, text in variants:
        generator.spec = _spec_with(shipped, json.loads(text))
        scores = [score_mesh(generator.generate(points, seed=0).mesh, reference,
                             seed=[0, index, 1])
                  for index, (points, reference) in enumerate(prepared)]

        def mean(key: str, scores: list = scores) -> float:
            return float(np.mean([s[key] for s in scores]))

        median = float(np.median([s["cd"] for s in scores]))
        print(f"{name:<28} CD {mean('cd') * 1e3:.3f}e-3  median {median * 1e3:.3f}e-3  "
              f"ECD {mean('ecd') * 1e2:.2f}e-2  EF1 {mean('ef1'):.3f}  "
              f"IN {mean('in') * 100:.1f}%  self-int {mean('self_intersections') * 100:.2f}%  "
              f"valid {mean('valid') * 100:.0f}%", flush=True)
    generator.spec = shipped
    return 0


if __name__ == "__main__":
    sys.exit(main())
