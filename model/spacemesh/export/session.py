"""One bounded training session: check, train a denoiser on a base, export, collect.

``scripts/gpu_train.sh`` runs this on a borrowed GPU machine (no package registry, a
time limit, and only a few files brought back), and it runs the same way on a CPU with a
tiny budget::

    python -m spacemesh.export.session --data data/qem-gpu --out "$OUT" --minutes 11

1. **Checks** before anything starts (exit 2, one line per problem): the Python modules
   training and export need (missing ones travel as wheels), the dataset, the base model
   and its sha256s, the device, a writable output folder, a budget that leaves time for
   the export.
2. **Trains** a diffusion-only run (:mod:`spacemesh.train.loop`) of ``--config`` on the
   base's frozen encoder, stopping with a checkpoint when the budget minus the export's
   reserve is spent (or on SIGTERM); ``--resume`` continues a run folder, also one
   brought back from another machine (``--base`` names the same base there).
3. **Exports** the run (only the denoiser graph is new; the base's encoder and
   connectivity graphs are copied).
4. **Collects** into ``--out`` at most eight files, none larger than 16 MiB:
   ``run/last.pt`` (with the optimiser, for ``--resume``; left out if too large),
   ``run/weights.pt`` (weights only), ``run/metrics.csv``, ``run/curves.png``,
   ``model/denoiser.onnx``, ``model/manifest.json`` and ``summary.json``. The model
   version is whole again next to its base: copy the base's ``encoder.onnx`` and
   ``connectivity.onnx`` beside ``model/`` (the manifest's sha256s check them).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

#: Modules the session imports (their pip names where they differ).
REQUIRED_MODULES = ("numpy", "scipy", "torch", "onnx", "onnxscript", "onnxruntime", "typer",
                    "rich", "tqdm", "matplotlib")

#: Seconds kept for the export and the collection at the end.
EXPORT_RESERVE = 120.0

#: Largest file brought back.
MAX_FILE_BYTES = 16 * 1024 * 1024


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m spacemesh.export.session",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="dataset folder (train split)")
    parser.add_argument("--out", type=Path, required=True, help="where the results go")
    parser.add_argument("--base", type=Path, default=Path("models/spacemesh-small/7"),
                        help="base model whose encoder and connectivity are kept")
    parser.add_argument("--config", default="small-local", help="config of the new denoiser")
    parser.add_argument("--run", type=Path, default=None,
                        help="run folder (default: OUT/../spacemesh-run, outside OUT)")
    parser.add_argument("--resume", action="store_true", help="continue the run folder")
    parser.add_argument("--minutes", type=float, default=11.0,
                        help="whole budget, export included")
    parser.add_argument("--device", default="cuda", help="cuda or cpu")
    parser.add_argument("--batch", type=int, default=None, help="shapes per step")
    parser.add_argument("--lr", type=float, default=None, help="peak learning rate")
    parser.add_argument("--steps", type=int, default=None,
                        help="step budget (the learning rate decays over it; default: "
                             "until the time is spent, at a constant rate)")
    parser.add_argument("--cache", type=int, default=4, help="augmentations cached per shape")
    parser.add_argument("--augment", default="none",
                        help="conditioning-cloud augmentation: none or realistic")
    parser.add_argument("--mix", type=Path, action="append", default=[],
                        help="another dataset whose train split joins --data's (repeatable)")
    parser.add_argument("--val-every", type=int, default=500, help="validate every N steps")
    parser.add_argument("--threads", type=int, default=0, help="CPU threads (0: default)")
    parser.add_argument("--version", type=int, default=8, help="version of the export")
    parser.add_argument("--name", default=None, help="model name of the export")
    parser.add_argument("--export-reserve", type=float, default=EXPORT_RESERVE,
                        help="seconds kept for the export")
    return parser


def preflight(args: argparse.Namespace) -> list[str]:
    """Everything that would stop the session later, found before it starts.

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    list of str
        One line per problem (empty: ready).
    """
    problems = []
    missing = [m for m in REQUIRED_MODULES if importlib.util.find_spec(m) is None]
    if missing:
        problems.append(f"missing Python modules: {', '.join(missing)} (carry them as wheels "
                        "in .whl/, see scripts/gpu_train.sh)")
    if not (args.data / "manifest.json").is_file():
        problems.append(f"--data {args.data}: no dataset there (no manifest.json)")
    for folder in args.mix:
        if not (folder / "manifest.json").is_file():
            problems.append(f"--mix {folder}: no dataset there (no manifest.json)")
    from spacemesh.data.augment import PRESETS

    if args.augment not in PRESETS:
        problems.append(f"--augment {args.augment}: choose from {', '.join(PRESETS)}")
    if not (args.base / "manifest.json").is_file():
        problems.append(f"--base {args.base}: no model version there (no manifest.json)")
    if args.minutes * 60.0 <= args.export_reserve + 30.0:
        problems.append(f"--minutes {args.minutes:g}: leaves no time to train after the "
                        f"{args.export_reserve:g} s kept for the export")
    if args.resume and not (_run_dir(args) / "checkpoints" / "last.pt").is_file():
        problems.append(f"--resume: no checkpoint in {_run_dir(args)}/checkpoints")
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        probe = args.out / ".write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as error:
        problems.append(f"--out {args.out}: not writable ({error.strerror})")
    if problems:  # the checks below import torch and read the base
        return problems
    from spacemesh.nn.base_model import BaseModel
    from spacemesh.nn.config import get_config

    try:
        get_config(args.config)
    except ValueError as error:
        problems.append(f"--config: {error}")
    try:
        BaseModel.load(args.base)
    except ValueError as error:
        problems.append(str(error))
    import torch

    if args.device.startswith("cuda") and not torch.cuda.is_available():
        problems.append("--device cuda: torch sees no GPU (use --device cpu to run on CPUs)")
    return problems


def _run_dir(args: argparse.Namespace) -> Path:
    return args.run if args.run is not None else args.out.parent / "spacemesh-run"


def _collect(run: Path, version_dir: Path | None, out: Path, summary: dict[str, Any]) -> None:
    """Copy what comes back into ``out`` (see the module docstring)."""
    import torch

    from spacemesh.train.checkpoint import latest_checkpoint

    (out / "run").mkdir(parents=True, exist_ok=True)
    last = latest_checkpoint(run)
    if last is not None:
        if last.stat().st_size <= MAX_FILE_BYTES:
            shutil.copyfile(last, out / "run" / "last.pt")
        else:
            summary["left_out"] = f"run/last.pt ({last.stat().st_size} bytes)"
        state = torch.load(last, map_location="cpu", weights_only=True)
        state["optimizer"] = {}  # weights only: what an export needs
        torch.save(state, out / "run" / "weights.pt")
    for name in ("metrics.csv", "curves.png"):
        if (run / name).is_file():
            shutil.copyfile(run / name, out / "run" / name)
    if version_dir is not None:
        (out / "model").mkdir(parents=True, exist_ok=True)
        for name in ("denoiser.onnx", "manifest.json"):
            shutil.copyfile(version_dir / name, out / "model" / name)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")


def main(argv: list[str] | None = None) -> int:
    """Run one session; returns the exit status (2: refused before starting)."""
    started = time.perf_counter()
    args = _parser().parse_args(argv)
    problems = preflight(args)
    if problems:
        for line in problems:
            print(f"gpu_train: cannot start: {line}", file=sys.stderr)
        return 2
    from spacemesh.export.repository import export_run
    from spacemesh.nn.config import get_config
    from spacemesh.train.loop import TrainOptions, train

    run = _run_dir(args)
    config = get_config(args.config)
    train_changes: dict[str, Any] = {
        "diffusion_only": True, "encoder_cache": args.cache, "checkpoint_minutes": 2.0,
        "val_every": args.val_every, "checkpoint_every": args.val_every,
        "augment": args.augment,
        "steps": args.steps or 10**7, "final_lr_ratio": 0.1 if args.steps else 1.0,
    }
    if args.batch:
        train_changes["batch_size"] = args.batch
    if args.lr:
        train_changes["lr"] = args.lr
    config = config.with_train(**train_changes)
    budget = args.minutes * 60.0 - args.export_reserve - (time.perf_counter() - started)
    summary_run = train(TrainOptions(
        config=config, data=args.data, out=run, resume=args.resume, device=args.device,
        threads=args.threads or None, max_seconds=budget, progress=False, base=args.base,
        steps=config.train.steps, mix=tuple(args.mix),
    ), log=lambda message: print(message, flush=True))
    summary: dict[str, Any] = {
        "steps": summary_run.steps, "train_seconds": round(summary_run.seconds, 1),
        "shapes": summary_run.metrics.get("shapes"), "device": args.device,
        "config": args.config, "base": str(args.base), "data": str(args.data),
        "mix": [str(m) for m in args.mix], "augment": args.augment,
        "validation": {k: v for k, v in summary_run.metrics.items() if k.startswith("val_")},
    }
    version_dir = None
    try:
        export_root = run / "export"
        version_dir = export_run(run, export_root, name=args.name, version=args.version,
                                 threads=args.threads)
        summary["export"] = str(version_dir)
    except (ValueError, OSError, RuntimeError) as error:  # the checkpoint still comes back
        summary["export_error"] = str(error)
        print(f"gpu_train: export failed: {error}", file=sys.stderr)
    summary["seconds"] = round(time.perf_counter() - started, 1)
    _collect(run, version_dir, args.out, summary)
    print(json.dumps(summary), flush=True)
    return 0 if version_dir is not None else 1


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
