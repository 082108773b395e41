"""Evaluate mesh repair (the issue's item 6, the paper's Sec. 5.5 numbers).

Three sets of inputs:

``synthetic``
    Held-out synthetic shapes (default ``data/qemflip-heldout-s2``: generated with a seed
    the training data does not use), each with a random region removed: a sphere around
    a random vertex holding about 8% of the vertices.
``cad``
    The closed CAD parts of ../shared/meshes (categories ``cad`` and ``cad-abc``,
    watertight), each with a random region removed (about 3% of the vertices, at most
    40).
``defective``
    The ``repair`` category of ../shared/meshes (open, non-manifold, pinched meshes):
    the region is every defect vertex with one ring of faces around it.

Methods, all given the same cut: ``ours`` (:func:`spacemesh.repair.repair_mesh`),
``meshfix`` (MeshFix on the mesh with the region removed; on the whole defective mesh
for ``defective``), ``trimesh`` (``trimesh.repair.fill_holes`` likewise) and ``hole``
(the cut mesh left as it is, for scale).

Metrics, in the original's [-1, 1] frame (Supplement C): Chamfer distance and F1 of
the whole surface against the original (the paper's numbers), the same restricted to
the region (points on the original's region faces against the prediction, and points on
the prediction's new faces against the original), the fraction of the faces outside the
region that come back identical (same positions, same polygon), and the manifold,
watertight and valid (closed oriented manifold) rates.

Writes ``docs/results/repair.md``, ``docs/results/repair.png`` (a gallery) and
``docs/results/repair.json`` (every row). ../shared/meshes is optional: without it
only the synthetic set runs. Usage::

    python experiments/eval_repair.py [--model DIR] [--count 100] [--steps N]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh.repair.patch import sub_mesh

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "meshes"
METHODS = ("ours", "meshfix", "trimesh", "hole")
#: Points sampled on the original's region (region metrics).
REGION_SAMPLES = 2000


def find_model(requested: str | None) -> tuple[Path, str]:
    """The model repository to evaluate, and how to label it."""
    from spacemesh.runtime.repository import default_model_dir, resolve_version_dir

    if requested:
        path = resolve_version_dir(requested)
        return path, path.parent.name
    shipped = default_model_dir()
    if shipped.exists():
        return resolve_version_dir(shipped), f"{shipped.name} (shipped default)"
    candidates = sorted((ROOT / "models").glob("*/*/manifest.json"))
    if not candidates:
        sys.exit("no model repository under models/; pass --model")
    best = candidates[-1].parent
    return best, f"{best.parent.name}/{best.name} (best available, not the shipped default)"


# ---------------------------------------------------------------------- regions
def random_region(mesh, rng: np.random.Generator, fraction: float, cap: int) -> dict:
    """A sphere around a random vertex holding about ``fraction`` of the vertices."""
    used = np.unique(mesh.face_indices)
    centre = mesh.vertices[rng.choice(used)]
    k = int(np.clip(round(fraction * len(used)), 2, cap))
    d = np.sort(np.linalg.norm(mesh.vertices[used] - centre, axis=1))
    radius = float(d[min(k, len(d) - 1)]) * 0.999
    return {"sphere": {"center": centre.tolist(), "radius": max(radius, 1e-9)}}


def defect_region(mesh) -> dict:
    """Every defect vertex and its neighbours (one ring of faces around the defects)."""
    from spacemesh.repair.cut import defect_vertices

    bad = defect_vertices(mesh)
    faces = np.zeros(mesh.n_faces, dtype=bool)
    faces[mesh.face_of_corner[bad[mesh.face_indices]]] = True
    ring = np.unique(mesh.face_indices[faces[mesh.face_of_corner]])
    return {"vertices": ring.tolist()}


# ---------------------------------------------------------------------- metrics
def face_keys(mesh, decimals: int = 6) -> list[tuple]:
    """Each face as its rotation-normalised tuple of rounded positions."""
    rounded = np.round(mesh.vertices, decimals) + 0.0
    keys = []
    for face in mesh.faces:
        pts = [tuple(rounded[v]) for v in face]
        start = min(range(len(pts)), key=pts.__getitem__)
        keys.append(tuple(pts[start:] + pts[:start]))
    return keys


def cut_mesh(mesh, region: np.ndarray):
    """The mesh without the region's faces (unused vertices dropped)."""
    return sub_mesh(mesh, np.flatnonzero(~region)).remove_unreferenced_vertices()[0]


def score(pred, original, region: np.ndarray, kept_keys: set, reference, centre, scale,
          seed: int) -> dict[str, Any]:
    """Whole-surface and region metrics of one prediction (see the module docstring)."""
    from spacemesh.metrics.distance import F1_THRESHOLD, chamfer_f1, f_score
    from spacemesh.metrics.quality import topology_flags
    from spacemesh.metrics.sampling import apply_normalisation, sample_mesh

    unit = apply_normalisation(pred, centre, scale)
    row: dict[str, Any] = topology_flags(pred)
    samples = sample_mesh(unit, reference["n"], seed)
    if len(samples) == 0:
        return {**row, "cd": math.nan, "f1": math.nan, "region_cd": math.nan,
                "region_f1": math.nan, "outside": 0.0}
    whole = chamfer_f1(samples.points, reference["all"].points, gt_tree=reference["tree"])
    keys = face_keys(pred)
    outside = sum(k in kept_keys for k in set(keys)) / max(len(kept_keys), 1)
    new = np.array([k not in kept_keys for k in keys])
    from scipy.spatial import cKDTree

    d_rec, _ = cKDTree(samples.points).query(reference["region"].points)
    rec = float(np.mean(d_rec < F1_THRESHOLD))
    if new.any():
        new_mesh = apply_normalisation(sub_mesh(pred, np.flatnonzero(new)), centre, scale)
        new_samples = sample_mesh(new_mesh, REGION_SAMPLES, seed)
        d_pre, _ = reference["tree"].query(new_samples.points) if len(new_samples) else (
            np.zeros(0), None)
    else:
        d_pre = np.zeros(0)
    pre = float(np.mean(d_pre < F1_THRESHOLD)) if len(d_pre) else 1.0
    region_cd = float(np.mean(d_rec**2) + (np.mean(d_pre**2) if len(d_pre) else 0.0))
    row.update(cd=whole.chamfer, f1=whole.f1, region_cd=region_cd,
               region_f1=f_score(pre, rec), outside=outside)
    return row


def prepare_reference(original, region: np.ndarray, seed: int) -> tuple[dict, Any, float]:
    from scipy.spatial import cKDTree

    from spacemesh.metrics.sampling import (
        N_SAMPLES,
        apply_normalisation,
        normalisation,
        sample_mesh,
    )

    centre, scale = normalisation(original)
    unit = apply_normalisation(original, centre, scale)
    everything = sample_mesh(unit, N_SAMPLES, seed)
    region_samples = sample_mesh(sub_mesh(unit, np.flatnonzero(region)), REGION_SAMPLES, seed)
    reference = {"n": N_SAMPLES, "all": everything, "tree": cKDTree(everything.points),
                 "region": region_samples}
    return reference, centre, scale


# ---------------------------------------------------------------------- one case
def timed(make: Callable[[], Any]) -> tuple[Any, str, float]:
    start = time.perf_counter()
    try:
        result = make()
    except Exception as error:  # a baseline crashing is a result, not a bug here
        return None, f"{type(error).__name__}: {error}"[:200], time.perf_counter() - start
    return result, "ok", time.perf_counter() - start


def evaluate_case(shape_id: str, category: str, mesh, region_json: dict, generator,
                  *, seed: int, steps: int | None, whole_for_baselines: bool
                  ) -> tuple[list[dict], dict]:
    """Every method on one mesh + region; returns rows and the meshes (for the gallery)."""
    from spacemesh.baselines.repair import fill_holes_trimesh, meshfix
    from spacemesh.repair import RegionError, plan_repair, repair_mesh

    base = {"shape": shape_id, "set": category, "vertices": mesh.n_vertices,
            "faces": mesh.n_faces}
    try:
        plan = plan_repair(mesh, region_json, generator.spec.max_vertices)
    except RegionError as error:
        return [{**base, "method": m, "status": f"region: {error.kind}"} for m in METHODS], {}
    region = plan.cut.region
    reference, centre, scale = prepare_reference(mesh, region, seed)
    kept_keys = set(face_keys(sub_mesh(mesh, np.flatnonzero(~region))))
    holed = cut_mesh(mesh, region)
    baseline_input = mesh if whole_for_baselines else holed
    outputs: dict[str, Any] = {}
    rows = []
    ours, status, seconds = timed(lambda: repair_mesh(mesh, region_json, generator, seed=seed,
                                                      steps=steps, plan=plan))
    extra = {}
    if ours is not None:
        s = ours.stats
        extra = {"new_vertices": s.new_vertices, "new_faces": s.new_faces,
                 "fallback": s.fallback, "region_faces": s.region_faces,
                 "grown_faces": s.grown_faces, "patch_rings": s.patch_rings,
                 "known_vertices": s.known_vertices, "candidates": s.candidates}
        ours = ours.mesh
    runs = {"ours": (ours, status, seconds),
            "meshfix": timed(lambda: meshfix(baseline_input)),
            "trimesh": timed(lambda: fill_holes_trimesh(baseline_input)),
            "hole": (holed, "ok", 0.0)}
    for method in METHODS:
        pred, status, seconds = runs[method]
        row = {**base, "method": method, "status": status, "seconds": seconds,
               "region_faces": int(region.sum())}
        if method == "ours":
            row.update(extra)
        if pred is not None:
            row.update(score(pred, mesh, region, kept_keys, reference, centre, scale, seed + 1))
            outputs[method] = pred
        rows.append(row)
    outputs["gt"] = mesh
    outputs["_unit"] = (centre, scale)
    outputs["_region_centre"] = mesh.vertices[
        mesh.face_indices[region[mesh.face_of_corner]]].mean(axis=0)
    return rows, outputs


# ---------------------------------------------------------------------- inputs
def synthetic_cases(directory: Path, count: int, seed: int):
    from spacemesh.data.shards import open_dataset

    dataset = open_dataset(directory)
    for i in range(min(count, len(dataset))):
        record = dataset[i]
        rng = np.random.default_rng([seed, i])
        yield record.shape_id, "synthetic", record.mesh, random_region(record.mesh, rng, 0.08,
                                                                         40), False


def shared_cases(seed: int):
    if not (MESHES / "manifest.csv").is_file():
        return
    from spacemesh.io import load_mesh

    with open(MESHES / "manifest.csv") as handle:
        rows = list(csv.DictReader(handle))
    for i, r in enumerate(rows):
        path = MESHES / r["file"]
        if not path.is_file():
            continue
        if r["category"] in ("cad", "cad-abc") and r["watertight"] == "True":
            mesh = load_mesh(path)
            rng = np.random.default_rng([seed, 1000 + i])
            yield r["file"], "cad", mesh, random_region(mesh, rng, 0.03, 40), False
        elif r["category"] == "repair":
            mesh = load_mesh(path)
            yield r["file"], "defective", mesh, defect_region(mesh), True


# ---------------------------------------------------------------------- report
def mean(values) -> float:
    values = [v for v in values if v is not None and not (isinstance(v, float) and
                                                           math.isnan(v))]
    return float(np.mean(values)) if values else math.nan


def summarise(rows: list[dict]) -> dict[tuple[str, str], dict]:
    out = {}
    for group in sorted({r["set"] for r in rows}):
        for method in METHODS:
            sel = [r for r in rows if r["set"] == group and r["method"] == method]
            scored = [r for r in sel if "cd" in r]
            out[(group, method)] = {
                "cases": len(sel), "scored": len(scored),
                "cd": mean([r["cd"] for r in scored]) * 1e3,
                "cd_median": float(np.nanmedian([r["cd"] for r in scored])) * 1e3
                if scored else math.nan,
                "f1": mean([r["f1"] for r in scored]),
                "region_cd": mean([r["region_cd"] for r in scored]) * 1e3,
                "region_f1": mean([r["region_f1"] for r in scored]),
                "outside": mean([r["outside"] for r in scored]),
                "manifold": mean([float(r["manifold"]) for r in scored]),
                "watertight": mean([float(r["watertight"]) for r in scored]),
                "valid": mean([float(r["valid"]) for r in scored]),
                "seconds": mean([r["seconds"] for r in scored]),
            }
    return out


def fmt(value: float, digits: int = 3) -> str:
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else (
        f"{value:.{digits}f}")


def write_report(rows: list[dict], config: dict, out: Path, gallery: Path | None) -> Path:
    summary = summarise(rows)
    lines = [
        "# Mesh repair: evaluation",
        "",
        f"Model: **{config['model_label']}** (`{config['model']}`), "
        f"{config['steps']} sampler steps, seed {config['seed']}. Written by "
        "`experiments/eval_repair.py`; every row is in `repair.json`.",
        "",
        f"Model training: {config.get('training', 'unknown')}.",
        "",
        "CD is the Chamfer distance (sum of the two mean squared distances, x 1e-3) and F1",
        "the F-score at 0.02, both in the original's [-1, 1] frame with 10,000 points per",
        "surface (Supplement C). *Region* CD/F1 compare only the region: points on the",
        "original's region faces against the prediction, and points on the prediction's",
        "new faces against the original. *Outside* is the fraction of the faces outside",
        "the region that come back identical (positions and polygon). *Valid* = closed,",
        "oriented, manifold. Paper (ABC, 100 shapes): ours CD 0.77, F1 0.76; MeshFix CD",
        "31.59, F1 0.72.",
        "",
        "| set | method | cases (scored) | CD mean | CD median | F1 | region CD | region F1 "
        "| outside | manifold | watertight | valid | seconds |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (group, method), s in summary.items():
        lines.append(
            f"| {group} | {method} | {s['cases']} ({s['scored']}) | {fmt(s['cd'], 2)} | "
            f"{fmt(s['cd_median'], 2)} | {fmt(s['f1'])} | {fmt(s['region_cd'], 2)} | "
            f"{fmt(s['region_f1'])} | {fmt(s['outside'])} | {fmt(s['manifold'], 2)} | "
            f"{fmt(s['watertight'], 2)} | {fmt(s['valid'], 2)} | {fmt(s['seconds'], 2)} |")
    ours = [r for r in rows if r["method"] == "ours"]
    failures: dict[str, int] = {}
    for r in ours:
        if r["status"] != "ok":
            failures[r["status"]] = failures.get(r["status"], 0) + 1
    fallbacks: dict[str, int] = {}
    for r in ours:
        if "fallback" in r:
            fallbacks[r["fallback"]] = fallbacks.get(r["fallback"], 0) + 1
    lines += [
        "",
        "## Our repairs",
        "",
        f"- fallback used (docs/REPAIR.md, splice rules): {json.dumps(fallbacks)}",
        f"- mean new vertices {fmt(mean([r.get('new_vertices') for r in ours]), 1)}, "
        f"new faces {fmt(mean([r.get('new_faces') for r in ours]), 1)}, region faces "
        f"{fmt(mean([r.get('region_faces') for r in ours]), 1)}, faces added by growth "
        f"{fmt(mean([r.get('grown_faces') for r in ours]), 2)}",
        f"- not repaired (status): {json.dumps(failures) if failures else 'none'}",
    ]
    defective = [r for r in rows if r["set"] == "defective" and r["method"] == "ours"]
    if defective:
        lines += ["", "## Defective meshes (region = every defect + one ring)", "",
                  "| mesh | faces | status | CD | valid |", "|---|---|---|---|---|"]
        for r in defective:
            lines.append(f"| {r['shape']} | {r['faces']} | {r['status']} | "
                         f"{fmt(r.get('cd', math.nan) * 1e3, 2)} | {r.get('valid', '')} |")
    if gallery is not None:
        lines += ["", f"![gallery]({gallery.name})", "",
                  "Gallery: the input with the region removed, ours, MeshFix, the original."]
    lines += ["", "Config: `" + json.dumps({k: v for k, v in config.items()
                                            if k not in ("model_label", "training")}) + "`",
              ""]
    path = out / "repair.md"
    path.write_text("\n".join(lines))
    return path


def facing(direction: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking the unit vector ``direction`` to ``target`` (Rodrigues)."""
    a = direction / max(np.linalg.norm(direction), 1e-12)
    b = target / np.linalg.norm(target)
    v, c = np.cross(a, b), float(a @ b)
    if np.linalg.norm(v) < 1e-9:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + k + k @ k / (1 + c)


def render(examples: list[tuple[str, dict]], path: Path) -> Path | None:
    """Each example turned so that its region faces the camera."""
    from spacemesh.evaluate.gallery import GalleryRow, render_gallery, view_direction
    from spacemesh.metrics.sampling import apply_normalisation

    rows = []
    for title, outputs in examples:
        centre, scale = outputs["_unit"]
        turn = facing(outputs["_region_centre"] - centre, view_direction())
        meshes = {k: apply_normalisation(m, centre, scale) for k, m in outputs.items()
                  if not k.startswith("_") and m is not None}
        meshes = {k: m.with_vertices(m.vertices @ turn.T) for k, m in meshes.items()}
        rows.append(GalleryRow(title[:28], np.zeros((0, 3)), meshes))
    if not rows:
        return None
    return render_gallery(rows, path, columns=("hole", "ours", "meshfix", "gt"),
                          labels={"hole": "region removed", "gt": "original"})


def _shown(path: Path) -> str:
    """``path`` relative to the repository when it is inside it (no machine paths in
    the report)."""
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def training_summary(model: Path) -> str:
    """One line on how the model was trained (from its manifest)."""
    manifest = json.loads((model / "manifest.json").read_text())
    training = manifest.get("training", {})
    data = manifest.get("data", {})
    held = manifest.get("metrics", {}).get("heldout", {}).get("connectivity_on_gt_vertices", {})
    steps = f"{training.get('steps', '?')} steps"
    if "base" in training:  # a connectivity-only run on a base model's encoder
        steps = (f"{training.get('connectivity_steps', '?')} connectivity steps (on the "
                 f"encoder of version {training['base'].get('version', '?')})")
    return (f"{steps} on {training.get('device', '?')} "
            f"({training.get('seconds', 0) / 60:.0f} min), data {data.get('dataset', '?')}; "
            f"held-out next accuracy on true vertices {held.get('next_accuracy', math.nan):.3f}, "
            f"decoded edge F1 {held.get('decoded_edge_f1', math.nan):.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--data", default=str(ROOT / "data" / "qemflip-heldout-s2"))
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", default=str(ROOT / "docs" / "results"))
    parser.add_argument("--no-shared", action="store_true", help="Skip ../shared/meshes.")
    parser.add_argument("--report-only", action="store_true",
                        help="Rewrite repair.md from an existing repair.json.")
    args = parser.parse_args()
    out = Path(args.out)
    if args.report_only:
        saved = json.loads((out / "repair.json").read_text())
        config = saved["config"]
        config.setdefault("training", training_summary(Path(config["model"])))
        gallery = out / "repair.png"
        print(write_report(saved["rows"], config, out, gallery if gallery.is_file() else None))
        return

    from spacemesh.evaluate.runner import pin_threads

    pin_threads(args.threads)
    from spacemesh.runtime import MeshGenerator

    model, label = find_model(args.model)
    generator = MeshGenerator.from_repository(model, threads=args.threads)
    steps = args.steps or generator.spec.steps
    out.mkdir(parents=True, exist_ok=True)
    cases = []
    if Path(args.data).is_dir():
        cases += list(synthetic_cases(Path(args.data), args.count, args.seed))
    else:
        print(f"{args.data}: no dataset; skipping the synthetic set", file=sys.stderr)
    if not args.no_shared:
        if MESHES.is_dir():
            cases += list(shared_cases(args.seed))
        else:
            print(f"{MESHES}: absent; skipping the real meshes", file=sys.stderr)
    rows: list[dict] = []
    examples: list[tuple[str, dict]] = []
    start = time.perf_counter()
    for n, (shape_id, group, mesh, region, whole) in enumerate(cases, start=1):
        case_rows, outputs = evaluate_case(shape_id, group, mesh, region, generator,
                                           seed=args.seed, steps=steps,
                                           whole_for_baselines=whole)
        rows.extend(case_rows)
        ours = case_rows[0]
        if outputs and len(examples) < 4 and group == "synthetic" and n % 7 == 1:
            examples.append((shape_id, outputs))
        print(f"[{n}/{len(cases)}] {group} {shape_id}: {ours['status']} "
              f"cd={ours.get('cd', math.nan) * 1e3:.2f}e-3 valid={ours.get('valid')} "
              f"({time.perf_counter() - start:.0f} s)", flush=True)
    gallery = render(examples, out / "repair.png")
    config = {"model": str(model), "model_label": label, "steps": steps, "seed": args.seed,
              "count": args.count, "data": _shown(Path(args.data)), "threads": args.threads,
              "shared_meshes": MESHES.is_dir() and not args.no_shared,
              "training": training_summary(model),
              "seconds": round(time.perf_counter() - start, 1)}
    (out / "repair.json").write_text(json.dumps({"config": config, "rows": rows}, indent=1,
                                                default=float))
    print(write_report(rows, config, out, gallery))


if __name__ == "__main__":
    main()
