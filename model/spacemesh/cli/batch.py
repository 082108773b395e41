"""``spacemesh batch``: mesh many files on Ray Data (a local Ray, or a cluster).

Every generate flag of ``spacemesh generate`` is taken as text and parsed by the same
rule (:func:`~spacemesh.cli.common.generate_options`, then
:meth:`~spacemesh.runtime.options.GenerateOptions.resolve` against the model once, before
Ray starts), so that a wrong value is one line and exit code 2 before any work, as for
the other commands. The workers then run exactly what ``spacemesh generate`` runs
(:mod:`spacemesh.batch.work`). Exit codes: 0 when every input has its output, 1 when some
inputs became error rows of the manifest, 2 for bad usage.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from spacemesh.cli.common import (
    FaceTypeFlag,
    RawFlag,
    SamplerFlag,
    SamplesFlag,
    SeedFlag,
    StartFlag,
    StartTimeFlag,
    StepsFlag,
    SurfaceFlag,
    TargetVerticesFlag,
    ToleranceFlag,
    app,
    fail,
    generate_options,
    option_flag,
    require_extra,
)


def _progress_line(row: dict[str, Any], done: int, total: int) -> str:
    """One line per finished input: ``[3/40] a.ply -> out/a.obj (0.41 s)``, or its error."""
    width = len(str(total))
    head = f"[{done:>{width}}/{total}] {row['input']}"
    if row.get("error_kind"):
        return f"{head}: error {row['error_kind']}: {row['error']}"
    return f"{head} -> {row['output']} ({row['seconds']:.2f} s)"


@app.command()
def batch(
    inputs: Annotated[list[str], typer.Argument(
        metavar="INPUTS...", show_default=False,
        help="Files, folders (every point cloud or mesh under them), globs, or @LIST "
        "(a text file naming one path or URL per line); local or any fsspec URL.")],
    out: Annotated[str, typer.Option(
        "--out", metavar="DIR", help="Output folder (local or an fsspec URL): one mesh per "
        "input and manifest.jsonl.")],
    workers: Annotated[int | None, typer.Option(
        "--workers", min=1, help="Workers, each loading the model once (default: as many "
        "as the cluster's CPUs allow at --threads-per-worker each).")] = None,
    threads_per_worker: Annotated[int, typer.Option(
        "--threads-per-worker", min=1, help="CPU threads of each worker.")] = 1,
    address: Annotated[str | None, typer.Option(
        "--address", help="Ray cluster to join (auto: the one this machine belongs to); "
        "default: a local Ray.")] = None,
    file_format: Annotated[str, typer.Option(
        "--format", help="Output format: obj, ply, off, glb or gltf.")] = "obj",
    repair: Annotated[str | None, typer.Option(
        "--repair", help="auto, holes or defects: repair mesh inputs (the automatic region "
        "of spacemesh repair --auto, --holes, --defects) instead of generating.")] = None,
    model: Annotated[Path | None, typer.Option(
        "--model", help="Model repository, as every worker sees it (default: the shipped "
        "model or $SPACEMESH_MODEL).")] = None,
    seed: SeedFlag = None,
    steps: StepsFlag = None,
    sampler: SamplerFlag = None,
    start: StartFlag = None,
    start_time: StartTimeFlag = None,
    target_vertices: TargetVerticesFlag = None,
    tolerance: ToleranceFlag = None,
    samples: SamplesFlag = None,
    raw: RawFlag = False,
    surface: SurfaceFlag = None,
    face_type: FaceTypeFlag = None,
    retry_errors: Annotated[bool, typer.Option(
        "--retry-errors", help="Run inputs with an error row again (by default a rerun "
        "retries only unreadable-input and internal-error rows).")] = False,
    progress: Annotated[bool, typer.Option(
        "--progress/--no-progress", help="One line on stderr per finished input.")] = True,
) -> None:
    """Mesh every input into DIR on Ray Data; a rerun skips the inputs already done."""
    require_extra("batch", "spacemesh batch", "ray", "fsspec")
    from spacemesh.batch.inputs import InputError, expand_inputs, split_url
    from spacemesh.batch.manifest import SettingsMismatch
    from spacemesh.batch.ray_job import run_batch
    from spacemesh.batch.work import OUTPUT_FORMATS, REPAIR_MODES, BatchSettings
    from spacemesh.runtime import MeshGenerator, ModelRepositoryError
    from spacemesh.runtime.options import GENERATE_ONLY, OptionError

    values = {"seed": seed, "steps": steps, "sampler": sampler, "start": start,
              "start_time": start_time, "target_vertices": target_vertices,
              "tolerance": tolerance, "samples": samples, "raw": raw, "surface": surface,
              "face_type": face_type}
    options = generate_options(**values)
    file_format = file_format.lower().lstrip(".")
    if file_format not in OUTPUT_FORMATS:
        fail(f"--format: expected one of {', '.join(OUTPUT_FORMATS)}, not {file_format!r}")
    if repair is not None:
        if repair not in REPAIR_MODES:
            fail(f"--repair: expected one of {', '.join(REPAIR_MODES)}, not {repair!r}")
        given = [name for name in GENERATE_ONLY if values[name] not in (None, False)]
        if given:
            fail(f"{option_flag(given[0])}: does not apply to --repair (it takes --seed, "
                 "--steps and --sampler)")
    try:
        generator = MeshGenerator.from_repository(model, threads=1)
    except ModelRepositoryError as error:
        fail(str(error))
    try:
        options.resolve(generator.spec)  # every range, before any worker starts
    except OptionError as error:
        fail(f"{option_flag(error.option)}: {error}")
    try:
        items = expand_inputs(inputs, repair=repair is not None)
    except InputError as error:
        fail(str(error))
    out_fs, out_root = split_url(out)
    if out_fs.isfile(out_root):
        fail(f"--out {out}: a file, not a folder")
    repository = generator.repository
    settings = BatchSettings(
        out=out, options=options, file_format=file_format, repair=repair,
        model=str(repository.path) if repository is not None else None,
        threads=threads_per_worker)

    def report(row: dict[str, Any], done: int, total: int) -> None:
        print(_progress_line(row, done, total), file=sys.stderr, flush=True)

    try:
        result = run_batch(items, settings, workers=workers, address=address,
                           retry_errors=retry_errors, progress=report if progress else None)
    except SettingsMismatch as error:
        fail(f"--out {out}: {error}")
    except ConnectionError as error:
        fail(f"--address {address}: {error}")
    typer.echo(f"{result.total} inputs: {result.succeeded} meshed, {result.failed} failed, "
               f"{result.skipped} already done ({result.workers} workers, "
               f"{result.seconds:.1f} s); manifest {result.manifest}")
    sources = {item.source for item in items}
    if any(row.get("error_kind") for row in result.rows if row["input"] in sources):
        raise typer.Exit(1)
