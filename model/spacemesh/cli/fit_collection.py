"""``spacemesh fit-collection``: the paper's mesh-collection autodecoder (Sec. 4.2)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from spacemesh.cli.common import Threads, app, fail, fit_progress, use_threads
from spacemesh.errors import SpaceMeshError


def _decode_run(run: Path, output: Path | None, device: str) -> None:
    from spacemesh.fitting.collection import decode_meshes, load_run
    from spacemesh.io import save_mesh

    if output is None:
        fail("--decode needs -o DIR (where the decoded meshes go)")
    try:
        model, state = load_run(run, device)
    except SpaceMeshError as error:
        fail(str(error))
    output.mkdir(parents=True, exist_ok=True)
    for name, mesh in decode_meshes(model, state):
        path = output / f"{Path(name).stem}.obj"
        save_mesh(mesh, path)
        typer.echo(f"wrote {path} ({mesh.n_vertices} vertices, {mesh.n_faces} faces)")



def _rate_option(help_text: str) -> typer.models.OptionInfo:
    """A learning-rate option: optional (the setting's default when not given), in (0, 1]."""
    return typer.Option(min=1e-7, max=1.0, show_default=False, help=help_text)

@app.command("fit-collection")
def fit_collection_command(
    mesh_paths: Annotated[
        list[Path] | None,
        typer.Argument(metavar="MESHES...", help="Closed manifold mesh files.", show_default=False),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", help="Run folder: checkpoint, log, scores, gallery.")
    ] = None,
    max_minutes: Annotated[
        float | None, typer.Option(min=0, help="Training time of this call (default: none).")
    ] = None,
    max_steps: Annotated[
        int | None, typer.Option(min=1, help="Total optimisation steps (default: none).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object last.")] = False,
    resume: Annotated[
        bool, typer.Option("--resume", help="Continue the run in --out (the same MESHES).")
    ] = False,
    decode_run: Annotated[
        Path | None,
        typer.Option("--decode", metavar="RUN",
                     help="Decode the trained run RUN into -o DIR (one .obj per mesh); "
                     "no training."),
    ] = None,
    output: Annotated[
        Path | None, typer.Option("-o", "--output", help="With --decode: the folder to write.")
    ] = None,
    device: Annotated[str, typer.Option(help="torch device: cpu or cuda.")] = "cpu",
    max_vertices: Annotated[
        int, typer.Option(min=1, help="Largest mesh accepted (the paper pads to 2000).")
    ] = 2000,
    batch_size: Annotated[int, typer.Option(min=1, help="Meshes per step.")] = 16,
    lr: Annotated[
        float | None, _rate_option("Learning rate of the decoder (default 3e-3); a resumed "
                                   "run takes this call's.")
    ] = None,
    code_lr: Annotated[
        float | None, _rate_option("Learning rate of the latent codes and the positional "
                                   "embedding (default 3e-2).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    gallery_rows: Annotated[int, typer.Option(min=0, help="Meshes in gallery.png.")] = 12,
    threads: Threads = 0,
) -> None:
    """Fit one autodecoder (a latent code per mesh, a shared transformer) to MESHES.

    Trains until every mesh decodes exactly or --max-minutes / --max-steps run out,
    checkpointing into --out (resume with --resume), then prints per-mesh and mean vertex
    L2, edge F1, `next` accuracy and exact-decode rate, and writes RUN/scores.json and
    RUN/gallery.png (decoded meshes next to their originals).
    `spacemesh fit-collection --decode RUN -o DIR` writes the decoded meshes as files.

    Exit code 0 when every mesh decodes exactly, 1 otherwise, 2 on bad input.
    """
    if device not in ("cpu", "cuda") and not device.startswith("cuda:"):
        fail(f"--device {device}: expected cpu or cuda")
    threads = use_threads(threads)  # before torch loads
    try:
        import torch

        from spacemesh.fitting.collection import (
            GALLERY,
            CollectionConfig,
            fit_collection,
            write_gallery,
        )
        from spacemesh.fitting.collection_data import load_collection
    except ModuleNotFoundError as error:
        fail(
            f"fitting needs the training extra ({error.name} is missing): "
            "pip install 'spacemesh[train]'"
        )
    if device.startswith("cuda") and not torch.cuda.is_available():
        fail("--device cuda: no CUDA device is available")
    if decode_run is not None:
        _decode_run(decode_run, output, device)
        return
    if not mesh_paths:
        fail("no MESHES given (or --decode RUN to decode a trained run)")
    if out is None:
        fail("--out RUN is required")
    if out.exists() and not resume and (out / "checkpoint.pt").exists():
        fail(f"{out} already holds a run: --resume to continue it, or another --out")
    if resume and not (out / "checkpoint.pt").is_file():
        fail(f"{out}: no checkpoint to resume")
    try:
        meshes = load_collection(mesh_paths, max_vertices)
    except SpaceMeshError as error:
        fail(str(error))
    from tqdm import tqdm

    rates: dict[str, Any] = {k: v for k, v in (("lr", lr), ("code_lr", code_lr)) if v is not None}
    config = CollectionConfig(
        batch_size=batch_size,
        seed=seed,
        max_steps=max_steps,
        max_seconds=None if max_minutes is None else 60.0 * max_minutes,
        threads=threads,
        device=device,
        **rates,
    )
    bar = tqdm(desc="fit-collection", unit="step", disable=as_json, leave=False)
    progress = fit_progress(bar)

    try:
        result = fit_collection(meshes, out, config, resume=resume, callback=progress)
    except SpaceMeshError as error:
        bar.close()
        fail(str(error))
    bar.close()
    if gallery_rows:
        write_gallery(meshes, result.scores, out / GALLERY, gallery_rows)
    summary = result.summary()
    if as_json:
        typer.echo(json.dumps(summary))
    else:
        for m in summary["meshes"]:
            typer.echo(
                f"{m['file']}: {'exact' if m['exact'] else 'NOT exact'}, "
                f"{m['n_vertices']} vertices, edge F1 {m['edge_f1']:.4f}, "
                f"next accuracy {m['next_accuracy']:.4f}, vertex L2 {m['vertex_l2']:.3g}"
            )
        typer.echo(
            f"{summary['n_exact']} of {summary['n_meshes']} exact after "
            f"{summary['iterations']} steps ({summary['seconds']:.1f} s); mean edge F1 "
            f"{summary['edge_f1']:.4f}, next accuracy {summary['next_accuracy']:.4f}, "
            f"vertex L2 {summary['vertex_l2']:.3g}; wrote {out}"
        )
    raise typer.Exit(0 if result.exact else 1)
