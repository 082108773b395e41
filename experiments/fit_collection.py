"""Build a mesh collection and fit it with ``spacemesh fit-collection``.

Collections (never committed; files are read from ../shared/meshes or written to /tmp):

- ``bar10``: the ten smallest closed, manifold, oriented meshes of the *test* split
  (experiments/real_meshes_split.csv) with at most 1,000 vertices, leaving out
  ``Schellenberg3__ForgeScan__abc7.stl``, which tuned single-mesh fitting (its hubs).
- ``dev10``: the same from the dev split (the tuning set of the bar's settings).
- ``fifty``: every closed, manifold, oriented mesh of ../shared/meshes with at most
  2,000 vertices, plus generator shapes (styles ``qem``, ``planar``, ``quad``, 64 to
  2,000 vertices) written as OBJ files, 50 meshes at least.
- ``synth``: generator shapes only (the tuning set: ``qem``, seed 21, 64 to 256 vertices).

Usage::

    python experiments/fit_collection.py bar10 --out /tmp/fc-bar10 --max-minutes 30 --threads 1
    python experiments/fit_collection.py fifty --out /tmp/fc-fifty --max-minutes 600 --threads 1

Prints the per-mesh table (markdown) and the summary from the command's ``--json`` line.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"
SPLIT = ROOT / "experiments" / "real_meshes_split.csv"
#: Left out of ``bar10``: it was used to tune single-mesh fitting.
SEEN = {"Schellenberg3__ForgeScan__abc7.stl"}


def closed_meshes(max_vertices: int) -> list[dict]:
    """Rows of manifest.csv: closed, manifold, oriented, at most ``max_vertices``."""
    with open(MESHES / "manifest.csv") as f:
        rows = list(csv.DictReader(f))
    good = [
        r for r in rows
        if all(r[k] == "True" for k in ("watertight", "edge_manifold", "vertex_manifold",
                                         "oriented"))
        and int(r["n_vertices"]) <= max_vertices
    ]
    return sorted(good, key=lambda r: (int(r["n_vertices"]), r["file"]))


def ten(split_name: str) -> list[Path]:
    """The ten smallest closed meshes of a split, up to 1,000 vertices (``bar10``: the
    test split without :data:`SEEN`; ``dev10``: the dev split, for tuning)."""
    with open(SPLIT) as f:
        split = {r["file"]: r["split"] for r in csv.DictReader(f)}
    rows = [r for r in closed_meshes(1000) if split.get(r["file"]) == split_name
            and r["file"] not in SEEN]
    return [MESHES / r["file"] for r in rows[:10]]


def synth_files(out: Path, style: str, count: int, seed: int, vertices: str) -> list[Path]:
    """Generator shapes written as OBJ files under ``out``."""
    from spacemesh.data.shards import open_dataset
    from spacemesh.io import save_mesh

    data = out / f"{style}-{seed}"
    if not (data / "manifest.json").is_file():
        subprocess.run(
            [sys.executable, "-m", "spacemesh.cli", "data", "synth", "--out", str(data),
             "--count", str(count), "--seed", str(seed), "--style", style,
             "--vertices", vertices, "--no-progress"],
            check=True,
        )
    paths = []
    for i, record in enumerate(open_dataset(data)):
        path = out / "obj" / f"{style}-{seed}-{i:03d}.obj"
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.is_file():
            save_mesh(record.mesh, path)
        paths.append(path)
    return paths


def fifty(work: Path) -> list[Path]:
    """Real closed meshes up to 2,000 vertices and generator shapes: 50 at least."""
    real = [MESHES / r["file"] for r in closed_meshes(2000)]
    per_style = max(0, 50 - len(real) + 2) // 3 + 1
    synth = []
    for k, style in enumerate(("qem", "planar", "quad")):
        synth += synth_files(work, style, per_style, 100 + k, "64:2000")
    return real + synth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("collection", choices=("bar10", "dev10", "fifty", "synth"))
    parser.add_argument("--out", type=Path, required=True, help="Run folder.")
    parser.add_argument("--max-minutes", type=float, default=30.0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--list", action="store_true", help="Only print the meshes.")
    parser.add_argument("--lr", type=float, help="Decoder learning rate (default 3e-3).")
    parser.add_argument("--code-lr", type=float, help="Codes' learning rate (default 3e-2).")
    args = parser.parse_args()
    work = Path("/tmp/fit-collection-meshes")
    if args.collection in ("bar10", "dev10"):
        paths = ten(args.collection[:-2].replace("bar", "test"))
    elif args.collection == "fifty":
        paths = fifty(work)
    else:
        paths = synth_files(work, "qem", 20, 21, "64:256")
    if args.list:
        print("\n".join(str(p) for p in paths))
        return
    command = [sys.executable, "-m", "spacemesh.cli", "fit-collection", *map(str, paths),
               "--out", str(args.out), "--max-minutes", str(args.max_minutes),
               "--threads", str(args.threads), "--json"]
    if args.resume:
        command.append("--resume")
    for flag, value in (("--lr", args.lr), ("--code-lr", args.code_lr)):
        if value is not None:
            command += [flag, str(value)]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode not in (0, 1):
        sys.exit(done.stderr.strip())
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    print("| mesh | V | F | vertex L2 | edge F1 | next accuracy | exact |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for m in summary["meshes"]:
        print(f"| `{m['file']}` | {m['n_vertices']} | {m['n_faces']} | {m['vertex_l2']:.2g} | "
              f"{m['edge_f1']:.4f} | {m['next_accuracy']:.4f} | {'yes' if m['exact'] else 'no'} |")
    print(f"| **mean** ({summary['n_meshes']} meshes) | | | {summary['vertex_l2']:.2g} | "
          f"{summary['edge_f1']:.4f} | {summary['next_accuracy']:.4f} | "
          f"{summary['n_exact']} of {summary['n_meshes']} |")
    summary.pop("meshes")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
