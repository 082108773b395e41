"""Whether repairs keep the topology of the surface: the Euler characteristic of the
mesh before and after ``spacemesh.repair.repair_mesh`` on random sphere regions (manual
``/repair`` regions) or on punched holes (``{"auto": "holes"}``), for the closed meshes
of a split of ../shared/meshes.

A region re-tessellated, or a hole capped, should change no handle: a manual repair
keeps the Euler characteristic, and capping each punched hole gives back the intact
mesh's (unless the punch cut a thin part through, which shows as more parts). Prints
one line a repair and the count of changes.

    python experiments/check_repair_genus.py --split dev --mode manual
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_repair import MESHES, cut_mesh, find_model, random_region
from eval_repair_holes import SPLIT, punched_cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("dev", "test"), default="dev")
    parser.add_argument("--mode", choices=("manual", "holes"), default="manual")
    parser.add_argument("--regions", type=int, default=3, help="manual regions a mesh")
    parser.add_argument("--max-vertices", type=int, default=3000)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"{MESHES}: absent; this check needs ../shared/meshes")
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.errors import SpaceMeshError
    from spacemesh.io import load_mesh
    from spacemesh.repair import repair_mesh
    from spacemesh.runtime import MeshGenerator
    from spacemesh.topology import check_topology

    model, _ = find_model(None)
    generator = MeshGenerator.from_repository(model, threads=args.threads)
    cases = []
    if args.mode == "holes":
        for name, _, mesh, region in punched_cases(0, 2, args.max_vertices, args.split):
            cases.append((name, mesh, cut_mesh(mesh, region), {"auto": "holes"}))
    else:
        with open(SPLIT) as handle:
            rows = [r for r in csv.DictReader(handle) if r["split"] == args.split]
        for i, r in enumerate(rows):
            if int(r["n_vertices"]) > args.max_vertices:
                continue
            mesh = load_mesh(MESHES / r["file"])
            if not check_topology(mesh).is_closed_oriented_manifold:
                continue
            rng = np.random.default_rng([1, i])
            for _ in range(args.regions):
                cases.append((r["file"], mesh, mesh, random_region(mesh, rng, 0.02, 30)))
    changed = done = 0
    for name, intact, source, region in cases:
        try:
            out = repair_mesh(source, region, generator, seed=0).mesh
        except SpaceMeshError as error:
            print(f"{name}: refused ({error})")
            continue
        before = check_topology(intact)
        after = check_topology(out)
        same = (before.euler_characteristic == after.euler_characteristic
                and before.n_components == after.n_components)
        done += 1
        changed += not same
        print(f"{name}: Euler characteristic {before.euler_characteristic} -> "
              f"{after.euler_characteristic}, parts {before.n_components} -> "
              f"{after.n_components}{'' if same else '  CHANGED'}", flush=True)
    print(f"changed {changed} of {done} repairs ({args.mode}, {args.split})")


if __name__ == "__main__":
    main()
