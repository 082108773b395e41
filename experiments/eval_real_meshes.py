"""Evaluate a model and the baselines on the real closed meshes of one split.

Reads ../shared/meshes. ``experiments/real_meshes_split.csv`` fixes which closed meshes
are ``dev`` (tuning) and which ``test`` (reporting): within each category (cad,
cad-abc, lowpoly, organic, polygon, polygon-cad), sorted by the sha256 of the file
name, alternately dev and test; it was written before any tuning. Only closed,
consistently oriented manifolds are used. Each mesh is
normalised (longest axis to [-1, 1]) and 2048 points with normals are sampled on it,
as for the synthetic datasets; then the same evaluation as ``spacemesh eval`` runs and
writes the same report, plus one table per category. The mesh files are never copied
into the repository; the script skips cleanly (exit 0) when the folder is absent.

Usage::

    python experiments/eval_real_meshes.py --split test [--model MODEL_REPO]
        [--out docs/results/real] [--modes default,raw,samples4,gt] [--noise 0.01]
        [--outliers 0.05] [--partial]
"""

from __future__ import annotations

import argparse
import csv
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CATEGORIES = ("cad", "cad-abc", "lowpoly", "organic", "polygon", "polygon-cad")
SPLIT_FILE = ROOT / "experiments" / "real_meshes_split.csv"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument(
        "--model", type=Path, default=None, help="model repository (default: the shipped model)"
    )
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "real")
    parser.add_argument("--categories", default=",".join(CATEGORIES))
    parser.add_argument("--split", choices=("dev", "test", "all"), default="test")
    parser.add_argument("--baselines", default="psr_star,psr_star_gt,psr_true,psr_true_gt")
    parser.add_argument("--modes", default="default")
    parser.add_argument("--noise", type=float, default=0.0)
    parser.add_argument("--partial", action="store_true")
    parser.add_argument("--outliers", type=float, default=0.0,
                        help="uniform outliers added, as a fraction of the points")
    parser.add_argument("--limit", type=int, default=None)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--gallery", type=int, default=6)
    parser.add_argument("--psr-star-target", choices=("ours", "gt"), default="ours")
    parser.add_argument("--title", default="SpaceMesh evaluation: real meshes")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args()
    manifest = args.meshes / "manifest.csv"
    if not manifest.is_file():
        print(f"skipped: {manifest} not found (the shared meshes are not on this machine)")
        return 0

    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)  # before pymeshlab and onnxruntime load
    from spacemesh.cli.evaluate import parse_baselines
    from spacemesh.evaluate.runner import mesh_shapes, parse_modes, run_evaluation, write_report
    from spacemesh.metrics.report import markdown_tables, summarise
    from spacemesh.runtime import MeshGenerator

    wanted = set(args.categories.split(","))
    paths, categories = split_meshes(args.meshes, args.split, wanted)
    shapes = mesh_shapes(paths, categories=categories, seed=args.seed)[: args.limit]
    generator = MeshGenerator.from_repository(args.model, threads=args.threads)
    result = run_evaluation(
        shapes,
        generator=generator,
        baselines=parse_baselines(args.baselines),
        seed=args.seed,
        steps=args.steps,
        gallery=args.gallery,
        threads=args.threads,
        psr_star_target=args.psr_star_target,
        progress=not args.no_progress,
        modes=parse_modes(args.modes),
        noise=args.noise,
        partial=args.partial,
        outliers=args.outliers,
    )
    result.config.update(
        model_path=str(generator.repository.path),
        data=f"../shared/meshes ({', '.join(sorted(wanted))}; split {args.split})",
    )
    command = "python experiments/eval_real_meshes.py " + shlex.join(sys.argv[1:])
    paths_out = write_report(result, args.out, title=args.title, command=command.strip())
    sections = [paths_out["table"].read_text()]
    for category in sorted(wanted):
        rows = [r for r in result.rows if r["category"] == category]
        if rows:
            count = len({r["shape_id"] for r in rows})
            sections += [f"\n## {category} ({count} meshes)\n", markdown_tables(summarise(rows))]
    paths_out["table"].write_text("\n".join(sections))
    print(paths_out["table"].read_text())
    return 0


def split_parser(doc: str, split: str = "dev") -> argparse.ArgumentParser:
    """A parser for a script over one split of the real meshes: the first line of
    ``doc`` as its description, with ``--meshes`` (../shared/meshes) and ``--split``."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument("--split", choices=("dev", "test", "all"), default=split)
    return parser


def split_meshes(meshes: Path, split: str, wanted: set[str]) -> tuple[list[Path], list[str]]:
    """The closed oriented manifold meshes of one split (``dev``, ``test`` or ``all``) and
    categories, sorted by category and vertex count, with their categories."""
    from spacemesh.io import load_mesh
    from spacemesh.topology import check_topology

    with SPLIT_FILE.open() as handle:
        chosen = {e["file"] for e in csv.DictReader(handle) if split in ("all", e["split"])}
    with (meshes / "manifest.csv").open() as handle:
        entries = [e for e in csv.DictReader(handle)
                   if e["category"] in wanted and e["file"] in chosen]
    paths, categories = [], []
    for entry in sorted(entries, key=lambda e: (e["category"], int(e["n_vertices"]))):
        path = meshes / entry["file"]
        if check_topology(load_mesh(path)).is_closed_oriented_manifold:
            paths.append(path)
            categories.append(entry["category"])
        else:
            print(f"skipped {entry['file']}: not a closed oriented manifold")
    return paths, categories


if __name__ == "__main__":
    sys.exit(main())
