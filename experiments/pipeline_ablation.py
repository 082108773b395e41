"""Full-pipeline quality of model repositories at chosen vertex spacings.

Each ``--case`` is ``MODEL_DIR`` or ``MODEL_DIR@SPACING`` (the model's own
``vertex_spacing`` when no spacing is given). Every case generates from the same
held-out shapes with the same seeds and prints one Markdown row of
:func:`spacemesh.train.evaluate.pipeline_metrics` (Chamfer mean and median, F1, vertices,
empty and valid shares). docs/MODEL.md's ablation table came from::

    spacemesh export runs/small-qem/checkpoints/step-0002000.pt --out /tmp/m2000 \\
        --calibrate-data data/qem-small-s1
    spacemesh export runs/small-qem/checkpoints/step-0003000.pt --out /tmp/m3000 \\
        --calibrate-data data/qem-small-s1
    python experiments/pipeline_ablation.py --data data/qem-heldout-s2 --shapes 48 \\
        --case /tmp/m2000/spacemesh-small@0.0001 --case /tmp/m3000/spacemesh-small@0.0001 \\
        --case /tmp/m3000/spacemesh-small --case models/spacemesh-small

(The export's own ``tau`` calibration is part of every row; ``@0.0001`` switches the
vertex spacing off, as the models before it had none.)
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path


def parse_case(text: str) -> tuple[Path, float | None]:
    """``DIR`` or ``DIR@SPACING``."""
    path, _, spacing = text.partition("@")
    return Path(path), (float(spacing) if spacing else None)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="held-out dataset folder")
    parser.add_argument("--case", action="append", required=True,
                        help="MODEL_DIR or MODEL_DIR@SPACING (repeatable)")
    parser.add_argument("--shapes", type=int, default=48)
    parser.add_argument("--steps", type=int, default=None, help="default: each model's")
    parser.add_argument("--threads", type=int, default=1, help="onnxruntime threads")
    args = parser.parse_args()

    from spacemesh.data.shards import first_records
    from spacemesh.runtime.pipeline import MeshGenerator
    from spacemesh.train.evaluate import pipeline_metrics

    if not (args.data / "manifest.json").is_file():
        print(f"error: {args.data}: not a dataset folder (no manifest.json)", file=sys.stderr)
        return 2
    records = None
    print("| model | vertex spacing | CD mean | CD median | F1 | vertices | empty | valid |")
    print("|---|---|---|---|---|---|---|---|")
    for text in args.case:
        path, spacing = parse_case(text)
        try:
            generator = MeshGenerator.from_repository(path, threads=args.threads)
        except Exception as error:
            print(f"error: {path}: {error}", file=sys.stderr)
            return 2
        if spacing is not None:
            generator.spec = replace(generator.spec, vertex_spacing=spacing)
        if records is None:
            records = first_records(args.data, max_vertices=generator.spec.max_vertices,
                                    limit=args.shapes)
        m = pipeline_metrics(generator, records, steps=args.steps)
        print(f"| {path} | {generator.spec.vertex_spacing:g} | {m['chamfer_mean']:.3f} | "
              f"{m['chamfer_median']:.3f} | {m['f1_mean']:.3f} | {m['vertices_mean']:.1f} | "
              f"{100 * m['empty']:.1f} % | {100 * m['valid']:.0f} % |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
