"""``spacemesh eval``: our model and the classic baselines on the same inputs, one report."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Annotated

import typer

from spacemesh.cli.common import Threads, UserError, app, use_threads, user_errors


def parse_baselines(text: str) -> list[str]:
    """``"psr,psr_star,bpa"`` -> a checked list (``"none"`` or empty: no baselines).

    Parameters
    ----------
    text : str

    Returns
    -------
    list of str
    """
    from spacemesh.evaluate.runner import BASELINES

    names = [t.strip() for t in text.split(",") if t.strip() and t.strip() != "none"]
    unknown = [n for n in names if n not in BASELINES]
    if unknown:
        raise UserError(
            f"--baselines: unknown {', '.join(unknown)}; choose from {', '.join(BASELINES)}"
        )
    return list(dict.fromkeys(names))


@app.command("eval")
@user_errors(FileNotFoundError, ValueError)
def evaluate(
    data: Annotated[
        Path,
        typer.Option("--data", help="A dataset folder (manifest.json) or a folder of mesh files."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Report folder (created).")],
    model: Annotated[
        Path | None,
        typer.Option(
            "--model", help="Model repository (default: the shipped model or $SPACEMESH_MODEL)."
        ),
    ] = None,
    baselines: Annotated[
        str, typer.Option("--baselines", help="Comma-separated: psr, psr_star, psr_star_gt, "
                          "psr_true, psr_true_gt, bpa (or none); psr_true: from the true "
                          "normals.")
    ] = "psr,psr_star,psr_true,bpa",
    split: Annotated[
        str, typer.Option("--split", help="Dataset split: train, val, test or all.")
    ] = "test",
    limit: Annotated[int | None, typer.Option("--limit", min=1, help="At most N shapes.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Sampler and metric seed.")] = 0,
    steps: Annotated[
        int | None, typer.Option("--steps", min=1, help="Sampler steps (default: the model's).")
    ] = None,
    gallery: Annotated[int, typer.Option("--gallery", min=0, help="Shapes in the gallery.")] = 4,
    threads: Threads = 1,  # 1 by default: every method's timing on one core
    psr_star_target: Annotated[
        str, typer.Option("--psr-star-target", help="PSR* vertex count: ours (per shape) or gt.")
    ] = "ours",
    no_model: Annotated[bool, typer.Option("--no-model", help="Run the baselines only.")] = False,
    modes: Annotated[
        str, typer.Option("--modes", help="Our pipeline's modes, comma-separated: default, "
                                          "raw, paper, samples4, gt, and the ablations "
                                          "no_fit, no_flips, no_sharp.")
    ] = "default",
    noise: Annotated[
        float, typer.Option("--noise", min=0.0, help="Gaussian noise on the input points "
                                                      "(fraction of the diagonal).")
    ] = 0.0,
    partial: Annotated[
        bool, typer.Option("--partial", help="Keep one side of the input points only.")
    ] = False,
    title: Annotated[str | None, typer.Option("--title", help="Report title.")] = None,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress bar.")
    ] = True,
) -> None:
    """Evaluate a model against PSR, PSR* and ball pivoting on the same inputs.

    Writes table.md (Table 1 and quality statistics), per_shape.csv and summary.json.

    Also histograms.png (Fig. 9) and gallery.png (points, ours, PSR*, ground truth).
    """
    threads = use_threads(threads)  # before pymeshlab and onnxruntime load
    from spacemesh.evaluate.runner import (
        load_shapes,
        parse_modes,
        run_evaluation,
        write_report,
    )
    from spacemesh.runtime import MeshGenerator, ModelRepositoryError

    if split not in ("train", "val", "test", "all"):
        raise UserError(f"--split must be train, val, test or all, not {split!r}")
    if psr_star_target not in ("ours", "gt"):
        raise UserError(f"--psr-star-target must be ours or gt, not {psr_star_target!r}")
    names = parse_baselines(baselines)
    shapes = load_shapes(data, split=split, limit=limit)
    if not shapes:
        raise UserError(f"{data}: no shapes in split {split!r}")
    generator = None
    if not no_model:
        try:
            generator = MeshGenerator.from_repository(model, threads=threads)
        except ModelRepositoryError as error:
            raise UserError(str(error)) from None
    result = run_evaluation(
        shapes,
        generator=generator,
        baselines=names,
        seed=seed,
        steps=steps,
        gallery=gallery,
        threads=threads,
        psr_star_target=psr_star_target,
        progress=progress,
        modes=parse_modes(modes),
        noise=noise,
        partial=partial,
    )
    if generator is not None and generator.repository is not None:
        result.config["model_path"] = str(generator.repository.path)
    result.config["data"] = str(data)
    command = ["spacemesh", "eval", "--data", str(data), "--out", str(out)]
    command += ["--no-model"] if no_model else ["--model", str(model)] if model else []
    command += [
        "--baselines",
        ",".join(names) or "none",
        "--split",
        split,
        "--seed",
        str(seed),
        "--threads",
        str(threads),
    ]
    command += ["--limit", str(limit)] if limit else []
    command += ["--psr-star-target", psr_star_target] if psr_star_target != "ours" else []
    command += ["--steps", str(steps)] if steps else []
    command += ["--modes", modes] if modes != "default" else []
    command += ["--noise", str(noise)] if noise else []
    command += ["--partial"] if partial else []
    command_line = shlex.join(command)
    paths = write_report(
        result, out, title=title or f"SpaceMesh evaluation: {data.name}", command=command_line
    )
    typer.echo((out / "table.md").read_text())
    typer.echo("wrote " + ", ".join(str(p) for p in paths.values()))
