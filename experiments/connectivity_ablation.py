"""Connectivity-network variants, each trained the same short way on the same base.

Every variant is the ``small`` connectivity network with some local-geometry features
switched off (or its width changed), trained with ``spacemesh train --base`` (connectivity
only, on the frozen encoder of ``--base``) for ``--steps`` steps of 10 connectivity steps,
with the same seed and batches. One Markdown row per variant: the train edge loss
(Eq. 3 per pair) and permutation loss averaged over the run, and at its end the
validation edge loss, edge F1 and ``next`` accuracy (24 shapes of the val split, learned
``tau``).
docs/MODEL.md's variant table came from::

    python experiments/connectivity_ablation.py --data data/qem-small-s1 \\
        --base models/spacemesh-small/1 --steps 80 --threads 2
"""

from __future__ import annotations

import argparse
import csv
import sys
from dataclasses import replace
from pathlib import Path

#: name -> changes to the ``small`` connectivity config
VARIANTS: dict[str, dict] = {
    "width 64, no local geometry (the previous network)": {
        "width": 64, "neighbours": 0, "geometric_attention": False},
    "width 64, geometric attention": {"width": 64, "neighbours": 0},
    "width 64, geometric attention + 16 neighbours": {"width": 64},
    "width 128, geometric attention": {"neighbours": 0},
    "width 128, geometric attention + 16 neighbours (small)": {},
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="training dataset folder")
    parser.add_argument("--base", type=Path, default=Path("models/spacemesh-small/1"))
    parser.add_argument("--out", type=Path, default=Path("runs/connectivity-ablation"))
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--only", action="append", help="variant names to run (repeatable)")
    args = parser.parse_args()

    from spacemesh.export.repository import load_trained_model
    from spacemesh.nn.config import get_config
    from spacemesh.train.loop import TrainOptions, train

    if not (args.data / "manifest.json").is_file():
        print(f"error: {args.data}: not a dataset folder (no manifest.json)", file=sys.stderr)
        return 2
    small = get_config("small")
    print("| variant | parameters | seconds | train edge | train perm | val edge | val edge F1 "
          "| val next |")
    print("|---|---|---|---|---|---|---|---|")
    for index, (name, changes) in enumerate(VARIANTS.items()):
        if args.only and name not in args.only:
            continue
        config = replace(small, connectivity=replace(small.connectivity, **changes))
        config = config.with_train(val_every=args.steps, checkpoint_every=args.steps,
                                   steps=args.steps)
        run = args.out / f"variant-{index}"
        summary = train(TrainOptions(config=config, data=args.data, out=run, base=args.base,
                                     threads=args.threads, progress=False),
                        log=lambda message: None)
        rows = list(csv.DictReader(open(run / "metrics.csv")))
        last = rows[-1]
        model, _ = load_trained_model(run)
        parameters = sum(p.numel() for p in model.connectivity.parameters())
        print(f"| {name} | {parameters / 1e6:.2f} M | {summary.seconds:.0f} "
              f"| {float(last['train_edge']):.4f} | {float(last['train_permutation']):.3f} "
              f"| {float(last['val_edge']):.4f} | {float(last['val_edge_f1']):.3f} "
              f"| {float(last['val_next_accuracy']):.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
