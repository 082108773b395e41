"""Trial (issue 47): where does the dense path lose against the issue's PyMeshLab trial?

For each mesh of a split, bare points, seed 0:

* ``default``: today's default (200 vertices);
* ``fit4_pml``: the full pipeline at 4x the count, then PyMeshLab's quadric edge collapse
  (topology kept) down to the count (the issue's trial; GPL, experiment only);
* ``fit4_ours``: the full pipeline at 4x, then ``spacemesh.geometry.simplify`` (point
  quadrics) down to the count, no fit after;
* ``fit4_ours_fit``: the same, then the geometry stage at the count;
* ``dense4``: today's ``dense_factor=4`` (raw dense decode, simplified, then fitted).

Usage::

    python experiments/compact_trial.py --split dev [--limit N] [--modes ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--split", default="dev")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--factor", type=float, default=4.0)
    parser.add_argument("--modes", default="default,fit4_pml,fit4_ours,fit4_ours_fit,dense4")
    parser.add_argument("--out", type=Path, default=Path("/tmp/compact_trial.csv"))
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    import pymeshlab
    from eval_real_meshes import CATEGORIES, split_meshes

    from spacemesh.evaluate.runner import mesh_shapes
    from spacemesh.geometry.intersections import self_intersection_fraction
    from spacemesh.geometry.simplify import simplify
    from spacemesh.geometry.stage import refine_geometry
    from spacemesh.mesh import PolygonMesh
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.metrics.sampling import apply_normalisation, normalisation
    from spacemesh.runtime import MeshGenerator

    paths, categories = split_meshes(ROOT.parent / "shared" / "meshes", args.split,
                                     set(CATEGORIES))
    shapes = mesh_shapes(paths, categories=categories, seed=0)[: args.limit]
    generator = MeshGenerator.from_repository(None, threads=1)
    modes = args.modes.split(",")
    dense = round(args.factor * args.count)
    rows = []
    for index, shape in enumerate(shapes):
        centre, scale = normalisation(shape.mesh)
        gt = apply_normalisation(shape.mesh, centre, scale)
        points = (np.asarray(shape.points, np.float64) - centre) / scale
        reference = Reference.from_mesh(gt, seed=[0, index, 0])
        fitted_dense = None
        for mode in modes:
            t0 = time.perf_counter()
            if mode == "default":
                mesh = generator.generate(points, None, seed=0, target_vertices=args.count).mesh
            elif mode == "dense4":
                spec = generator.spec
                generator.spec = replace(spec, geometry=replace(spec.geometry,
                                                                dense_factor=args.factor))
                try:
                    mesh = generator.generate(points, None, seed=0,
                                              target_vertices=args.count).mesh
                finally:
                    generator.spec = spec
            else:
                if fitted_dense is None:
                    fitted_dense = generator.generate(points, None, seed=0,
                                                      target_vertices=dense).mesh
                if mode == "fit4_pml":
                    ms = pymeshlab.MeshSet()
                    tri = fitted_dense.face_indices.reshape(-1, 3)
                    ms.add_mesh(pymeshlab.Mesh(fitted_dense.vertices, tri))
                    ms.meshing_decimation_quadric_edge_collapse(
                        targetfacenum=2 * args.count - 4 + 4 * 0, preservetopology=True,
                        preservenormal=True, optimalplacement=True, planarquadric=True,
                        qualitythr=0.3)
                    m = ms.current_mesh()
                    f = m.face_matrix()
                    mesh = PolygonMesh(m.vertex_matrix(), f.reshape(-1),
                                       np.arange(0, f.size + 1, 3))
                else:
                    mesh = simplify(fitted_dense, points, None,
                                    target_vertices=args.count).mesh
                    if mode == "fit4_ours_fit":
                        mesh = refine_geometry(mesh, points, None,
                                               generator.spec.geometry).mesh
            seconds = time.perf_counter() - t0
            row = score_mesh(mesh, reference)
            crossing = self_intersection_fraction(mesh)
            rows.append(dict(shape=shape.shape_id, category=shape.category, mode=mode,
                             cd=row["cd"], ecd=row["ecd"], ef1=row["ef1"],
                             in_=row["in"], topology=row["topology"], valid=row["valid"],
                             crossing=crossing, n_vertices=mesh.n_vertices, s=seconds))
            print(f"{shape.shape_id:30s} {mode:14s} cd {row['cd']*1e3:6.2f} "
                  f"ecd {row['ecd']*1e2:6.2f} ef1 {row['ef1']:.3f} in {row['in']*100:5.1f} "
                  f"topo {int(row['topology'])} cross {crossing:.3f} "
                  f"v {mesh.n_vertices} {seconds:.1f}s", flush=True)
    import csv

    with args.out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print()
    for mode in modes:
        sel = [r for r in rows if r["mode"] == mode]
        print(f"{mode:14s} cd {np.mean([r['cd'] for r in sel])*1e3:.3f} "
              f"median {np.median([r['cd'] for r in sel])*1e3:.3f} "
              f"ecd {np.mean([r['ecd'] for r in sel])*1e2:.2f} "
              f"ef1 {np.mean([r['ef1'] for r in sel]):.3f} "
              f"in {np.mean([r['in_'] for r in sel])*100:.1f} "
              f"topo {np.mean([r['topology'] for r in sel])*100:.0f}% "
              f"valid {np.mean([r['valid'] for r in sel])*100:.0f}% "
              f"cross {np.mean([r['crossing'] for r in sel])*100:.2f}% "
              f"s {np.mean([r['s'] for r in sel]):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
