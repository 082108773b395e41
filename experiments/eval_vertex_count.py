"""Quality and latency of large meshes: each pipeline against ``target_vertices``.

For every shape (dev-split real meshes of ../shared/meshes, and generator shapes of
1,024 to 2,048 vertices) and every target, the points (8,192 area-uniform samples of the
normalised mesh, no normals) go through each method, and the output is scored against
the mesh's surface (``spacemesh.metrics``: CD, EF1, IN, validity, self-intersections).

Methods:

- ``default``: the default pipeline as it stands;
- ``split``: the default before large meshes (at most ``max_vertices`` tokens through the
  networks; the geometry stage splits edges up to the target);
- ``raw``: ``raw=True`` (every target token through the connectivity network, no geometry
  stage);
- ``tokens``: ``ModelSpec.large_meshes = "tokens"``: every target vertex up to 2,048
  through the connectivity network (with its fallback to ``split``), then the geometry
  stage; the same as ``default`` unless a manifest chooses otherwise;
- ``psr_star``: screened Poisson on estimated normals, decimated to the default's count.

Usage::

    python experiments/eval_vertex_count.py --targets 256,512,1024,2048 \
        --methods default,split,raw,psr_star --out /tmp/vc.csv
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SPLIT_FILE = ROOT / "experiments" / "real_meshes_split.csv"
#: Dev meshes of at least ~600 vertices, across the categories (tuning only).
DEV_MESHES = (
    "mikedh__trimesh__plate_holes.STL",
    "mikedh__trimesh__fandisk.obj",
    "odedstein__meshes__wingnut.obj",
    "Schellenberg3__ForgeScan__abc8.stl",
    "odedstein__meshes__torus.obj",
    "odedstein__meshes__bunny.obj",
    "mlivesu__cinolib__cubespikes.obj",
    "libigl__libigl-tutorial-data__horse_quad.obj",
)
POINTS = 8192
#: Methods that are the default pipeline with one way of making large meshes
#: (:attr:`spacemesh.runtime.spec.ModelSpec.large_meshes`).
LARGE_MODES = {"split": "split", "tokens": "tokens"}


def real_shapes(meshes: Path, limit: int | None) -> list[tuple[str, object, np.ndarray]]:
    """(name, normalised mesh, points) of the dev meshes."""
    from spacemesh.evaluate.runner import mesh_shapes

    with SPLIT_FILE.open() as handle:
        dev = {e["file"] for e in csv.DictReader(handle) if e["split"] == "dev"}
    names = [n for n in DEV_MESHES if n in dev and (meshes / n).is_file()][:limit]
    shapes = mesh_shapes([meshes / n for n in names], points=POINTS, seed=0)
    return [(s.shape_id, s.mesh, np.asarray(s.points, np.float64)) for s in shapes]


def synth_shapes(count: int, seed: int) -> list[tuple[str, object, np.ndarray]]:
    """Generator shapes (qem style) of 1,024 to 2,048 vertices."""
    from spacemesh.data.synth import SynthConfig, make_shape
    from spacemesh.primitives import normalize, sample_surface

    config = SynthConfig(count=count, seed=seed, style="qem", vertex_min=1024,
                         vertex_max=2048, points=POINTS)
    out = []
    for index in range(count):
        shape, _, _ = make_shape(config, index)
        if shape is None:
            continue
        mesh, _, _ = normalize(shape["mesh"])
        points, _ = sample_surface(mesh, POINTS, np.random.default_rng([seed, index]))
        out.append((shape["record"]["shape_id"], mesh, np.asarray(points, np.float64)))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument("--targets", default="256,512,1024,2048")
    parser.add_argument("--methods", default="default,split,raw,psr_star")
    parser.add_argument("--real", type=int, default=8, help="dev meshes (0: none)")
    parser.add_argument("--synth", type=int, default=3, help="generator shapes (0: none)")
    parser.add_argument("--synth-seed", type=int, default=11)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("/tmp/vertex_count.csv"))
    args = parser.parse_args()

    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.baselines import estimate_normals, psr_star, screened_poisson
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.runtime import MeshGenerator

    generator = MeshGenerator.from_repository(threads=args.threads)
    targets = [int(t) for t in args.targets.split(",")]
    methods = args.methods.split(",")
    shapes = (real_shapes(args.meshes, args.real) if args.real else [])
    shapes += synth_shapes(args.synth, args.synth_seed) if args.synth else []
    rows = []
    fields = ["shape", "target", "method", "seconds", "n_vertices", "cd", "ef1", "in",
              "valid", "self_intersections", "connectivity_s", "geometry_s"]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for name, mesh, points in shapes:
            reference = Reference.from_mesh(mesh)
            psr = None
            for target in targets:
                counts = {}
                for method in methods:
                    timings: dict[str, float] = {}
                    start = time.perf_counter()
                    if method == "psr_star":
                        if psr is None:
                            psr = screened_poisson(points, estimate_normals(points))
                        out = psr_star(psr, counts.get("default", target))
                    else:
                        spec = generator.spec
                        if method in LARGE_MODES:
                            generator.spec = replace(spec, large_meshes=LARGE_MODES[method])
                        try:
                            result = generator.generate(points, target_vertices=target,
                                                        raw=method == "raw")
                        finally:
                            generator.spec = spec
                        out, timings = result.mesh, result.timings
                        counts[method] = out.n_vertices
                    seconds = time.perf_counter() - start
                    score = score_mesh(out, reference)
                    row = {"shape": name, "target": target, "method": method,
                           "seconds": round(seconds, 3), "n_vertices": out.n_vertices,
                           "cd": score["cd"], "ef1": score["ef1"], "in": score["in"],
                           "valid": score["valid"],
                           "self_intersections": score["self_intersections"],
                           "connectivity_s": round(timings.get("connectivity", 0.0), 3),
                           "geometry_s": round(timings.get("geometry", 0.0), 3)}
                    rows.append(row)
                    writer.writerow(row)
                    handle.flush()
                    print(f"{name[:40]:40s} {target:5d} {method:9s} {seconds:6.2f}s "
                          f"V={out.n_vertices:5d} CD={score['cd'] * 1e3:6.2f} "
                          f"EF1={score['ef1']:.3f} valid={score['valid']} "
                          f"SI={score['self_intersections']:.4f}", flush=True)
    print_summary(rows, targets, methods)
    return 0


def print_summary(rows: list[dict], targets: list[int], methods: list[str]) -> None:
    """One markdown table: per target and method, medians and rates over the shapes."""
    print("\n| target | method | shapes | #V (median) | CD 1e-3 (median) | EF1 (mean) | "
          "IN % (mean) | valid | self-int. % (mean) | seconds (median) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for target in targets:
        for method in methods:
            chosen = [r for r in rows if r["target"] == target and r["method"] == method]
            if not chosen:
                continue

            def values(key: str, rows: list[dict] = chosen) -> np.ndarray:
                return np.array([float(r[key]) for r in rows], dtype=np.float64)

            cd = values("cd")
            print(f"| {target} | {method} | {len(chosen)} | "
                  f"{np.median(values('n_vertices')):.0f} | "
                  f"{np.nanmedian(cd) * 1e3 if not np.isnan(cd).all() else math.nan:.2f} | "
                  f"{np.nanmean(values('ef1')):.3f} | {np.nanmean(values('in')) * 100:.1f} | "
                  f"{sum(bool(r['valid']) for r in chosen)}/{len(chosen)} | "
                  f"{np.nanmean(values('self_intersections')) * 100:.2f} | "
                  f"{np.median(values('seconds')):.2f} |")


if __name__ == "__main__":
    sys.exit(main())
