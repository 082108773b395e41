"""``spacemesh train`` and ``spacemesh export``: train the networks, write a model repository.

Several GPUs or nodes: ``torchrun --nproc_per_node K $(which spacemesh) train ...`` (one
process per GPU; DistributedDataParallel, NCCL on GPUs and gloo on CPUs).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from spacemesh.cli.common import Threads, app, fail, require_extra, use_threads


def _require_torch() -> None:
    require_extra("train", "training", "torch")


def _mode_options(model_config, *, resume: bool, diffusion_only: bool,
                  encoder_cache: int | None, augment: str | None,
                  checkpoint_minutes: float | None, warm_start: bool = False):
    """``model_config`` with the diffusion-only, cache, augmentation and checkpoint-timer
    options applied (a one-line exit for those a resumed run cannot change)."""
    from spacemesh.data.augment import get_augment

    if resume and (diffusion_only or encoder_cache is not None or augment is not None
                   or warm_start):
        fail("--diffusion-only, --encoder-cache, --augment and --warm-start apply to new "
             "runs (a resumed run keeps its own)")
    if warm_start:
        if not diffusion_only:
            fail("--warm-start applies to --diffusion-only runs on a --base")
        model_config = model_config.with_train(warm_start=True)
    if diffusion_only:
        model_config = model_config.with_train(diffusion_only=True)
    if encoder_cache is not None:
        if not diffusion_only:
            fail("--encoder-cache applies to --diffusion-only runs")
        model_config = model_config.with_train(encoder_cache=encoder_cache)
    if augment is not None:
        try:
            get_augment(augment)
        except ValueError as error:
            fail(str(error))
        model_config = model_config.with_train(augment=augment)
    if checkpoint_minutes is not None:
        model_config = model_config.with_train(checkpoint_minutes=checkpoint_minutes)
    return model_config


@app.command()
def train(
    config: Annotated[
        str, typer.Option("--config", help="tiny, small, paper, tiny-local or small-local.")
    ] = "small",
    data: Annotated[Path, typer.Option("--data", help="Dataset folder (its train split).")] = Path(
        "data"
    ),
    out: Annotated[Path, typer.Option("--out", help="Run folder.")] = Path("runs/small"),
    resume: Annotated[
        bool, typer.Option("--resume", help="Continue from the run's last checkpoint.")
    ] = False,
    steps: Annotated[
        int | None, typer.Option("--steps", min=1, help="Diffusion steps (overrides the config).")
    ] = None,
    val_data: Annotated[
        Path | None, typer.Option("--val-data", help="Held-out dataset (default: the val split).")
    ] = None,
    lr: Annotated[
        float | None,
        typer.Option("--lr",
                     help="Peak Adam learning rate (default: the config's; lower it to "
                     "fine-tune)."),
    ] = None,
    connectivity_jitter: Annotated[
        float | None,
        typer.Option("--connectivity-jitter", min=0.0,
                     help="Noise (std, [-1, 1] frame) on the vertices the connectivity "
                     "network trains on (default: the config's; applies on --resume too)."),
    ] = None,
    false_positive_weight: Annotated[
        float | None,
        typer.Option("--false-positive-weight", min=0.0,
                     help="Weight of the non-edges below the threshold in the edge loss "
                     "(hard negatives; default: the config's, the paper's lambda)."),
    ] = None,
    device: Annotated[
        str | None, typer.Option("--device", help="cpu or cuda (default: cuda if available).")
    ] = None,
    threads: Threads = 0,
    seed: Annotated[int, typer.Option("--seed", help="Random seed.")] = 0,
    max_minutes: Annotated[
        float | None,
        typer.Option("--max-minutes", min=0, help="Stop (with a checkpoint) after this long."),
    ] = None,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress bar.")
    ] = True,
    base: Annotated[
        Path | None,
        typer.Option("--base", help="A model version folder: train only the config's "
                     "connectivity network (with --diffusion-only: its denoiser) on the "
                     "base's frozen encoder; the base's other graphs are kept."),
    ] = None,
    init_from: Annotated[
        Path | None,
        typer.Option("--init-from", help="Fine-tune: start from this run's (or checkpoint's, "
                     "or exported connectivity-only model version folder's) weights, with a "
                     "new optimiser and schedule (a connectivity-only run's base is "
                     "inherited)."),
    ] = None,
    diffusion_only: Annotated[
        bool,
        typer.Option("--diffusion-only", help="Train the denoiser alone on a frozen encoder "
                     "(--base's, or --init-from's); no connectivity step is taken."),
    ] = False,
    encoder_cache: Annotated[
        int | None,
        typer.Option("--encoder-cache", min=0, help="With --diffusion-only: augmented "
                     "variants per training shape whose frozen-encoder volumes are cached "
                     "(0: no cache; default: the config's, 4)."),
    ] = None,
    augment: Annotated[
        str | None,
        typer.Option("--augment", help="Conditioning-cloud augmentation: none (the clean "
                     "samples) or realistic (noise, uneven density, missing regions, "
                     "outliers); default: the config's, none."),
    ] = None,
    mix: Annotated[
        list[Path] | None,
        typer.Option("--mix", help="Another dataset whose train split joins --data's "
                     "(repeatable; e.g. other generator styles)."),
    ] = None,
    checkpoint_minutes: Annotated[
        float | None,
        typer.Option("--checkpoint-minutes", min=0.0, help="Also write a checkpoint every "
                     "this many minutes (0: only every checkpoint_every steps; applies on "
                     "--resume too)."),
    ] = None,
    warm_start: Annotated[
        bool,
        typer.Option("--warm-start", help="With --diffusion-only and --base: start the new "
                     "denoiser from the base's (a local-point denoiser: the shared weights, "
                     "and local attention that starts silent) instead of fresh weights."),
    ] = False,
) -> None:
    """Train the encoder, denoiser and connectivity network on a dataset."""
    _require_torch()
    from spacemesh.nn.config import get_config
    from spacemesh.train.loop import TrainOptions
    from spacemesh.train.loop import train as run_training

    try:
        model_config = get_config(config)
    except ValueError as error:
        fail(str(error))
    if connectivity_jitter is not None:
        model_config = model_config.with_train(connectivity_jitter=connectivity_jitter)
    if false_positive_weight is not None:
        if resume:
            fail("--false-positive-weight applies to new runs (a resumed run keeps its loss)")
        model_config = model_config.with_train(false_positive_weight=false_positive_weight)
    if lr is not None:
        if not lr > 0:
            fail(f"--lr must be positive (got {lr})")
        if resume:
            fail("--lr applies to new runs (a resumed run keeps its learning rate)")
        model_config = model_config.with_train(lr=lr)
    model_config = _mode_options(model_config, resume=resume, diffusion_only=diffusion_only,
                                 encoder_cache=encoder_cache, augment=augment,
                                 checkpoint_minutes=checkpoint_minutes, warm_start=warm_start)
    if diffusion_only and not resume and base is None and init_from is None:
        fail("--diffusion-only freezes a trained encoder: give --base or --init-from")
    if warm_start and base is None:
        fail("--warm-start starts from the --base model's denoiser: give --base")
    if not (data / "manifest.json").is_file():
        fail(f"{data}: not a dataset folder (no manifest.json)")
    for folder in mix or ():
        if not (folder / "manifest.json").is_file():
            fail(f"{folder}: not a dataset folder (no manifest.json)")
    if val_data is not None and not (val_data / "manifest.json").is_file():
        fail(f"{val_data}: not a dataset folder (no manifest.json)")
    options = TrainOptions(
        config=model_config, data=data, out=out, resume=resume, steps=steps, val_data=val_data,
        device=device, threads=use_threads(threads), seed=seed,
        max_seconds=None if max_minutes is None else max_minutes * 60, progress=progress,
        base=base, init_from=init_from, mix=tuple(mix or ()),
    )
    try:
        summary = run_training(options, log=lambda m: typer.echo(m, err=True))
    except (FileNotFoundError, ValueError) as error:
        fail(str(error))
    typer.echo(f"trained {summary.steps} steps in {summary.seconds:.0f} s; "
               f"checkpoint {summary.checkpoint}")


@app.command("export")
def export_(
    run: Annotated[Path, typer.Argument(help="Run folder (or a checkpoint file), or a model "
                                        "version folder to repackage with today's decode.")],
    out: Annotated[Path, typer.Option("--out", help="Model repository root.")] = Path("models"),
    name: Annotated[
        str | None, typer.Option("--name", help="Model name (default spacemesh-<config>).")
    ] = None,
    version: Annotated[int, typer.Option("--version", min=1, help="Model version.")] = 1,
    eval_data: Annotated[
        Path | None,
        typer.Option("--eval-data", help="Held-out dataset to measure into the manifest."),
    ] = None,
    calibrate_data: Annotated[
        Path | None,
        typer.Option("--calibrate-data", help="Dataset whose val split recalibrates tau "
                     "and chooses the vertex spacing."),
    ] = None,
    eval_shapes: Annotated[
        int, typer.Option("--eval-shapes", min=1, help="Shapes for connectivity metrics.")
    ] = 100,
    pipeline_shapes: Annotated[
        int, typer.Option("--pipeline-shapes", min=1, help="Shapes for full-pipeline metrics.")
    ] = 16,
    threads: Threads = 0,
) -> None:
    """Export a run as a model repository: OUT/NAME/VERSION/{*.onnx, manifest.json}.

    Given a model version folder instead (one with a manifest.json), write its graphs
    byte for byte as a new version with the decode of this release, measured again.
    """
    _require_torch()
    from spacemesh.export.repository import export_run, repackage_repository

    threads = use_threads(threads)
    if not run.exists():
        fail(f"{run}: no such run folder or checkpoint")
    for folder in (eval_data, calibrate_data):
        if folder is not None and not (folder / "manifest.json").is_file():
            fail(f"{folder}: not a dataset folder (no manifest.json)")
    export = repackage_repository if (run / "manifest.json").is_file() else export_run
    try:
        directory = export(
            run, out, name=name, version=version, eval_data=eval_data,
            calibrate_data=calibrate_data,
            connectivity_shapes=eval_shapes, pipeline_shapes=pipeline_shapes, threads=threads,
        )
    except (FileNotFoundError, ValueError) as error:
        fail(str(error))
    typer.echo(str(directory))
