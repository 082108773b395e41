"""``spacemesh data``: synthesise, import and describe training datasets."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from spacemesh.cli.common import UserError, app, require_extra, user_errors

data_app = typer.Typer(
    name="data",
    help="Training data: synthetic CSG shapes, imported mesh folders, statistics.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.add_typer(data_app, name="data")


#: Modules of the geometry extra that ``data synth`` builds and re-meshes shapes with
#: (each failed attempt would otherwise count as a rejected shape).
SYNTH_MODULES = ("manifold3d", "pymeshlab")


def parse_vertex_range(text: str) -> tuple[int, int]:
    """Parse ``MIN:MAX`` (e.g. ``128:512``) into two ints.

    Parameters
    ----------
    text : str

    Returns
    -------
    (int, int)
    """
    parts = text.split(":")
    try:
        low, high = (int(p) for p in parts)
    except ValueError:
        raise UserError(f"--vertices must look like MIN:MAX, e.g. 128:512, not {text!r}") from None
    if not 4 <= low <= high:
        raise UserError(f"--vertices {text}: need 4 <= MIN <= MAX")
    return low, high


def _positive(**values: int | None) -> None:
    """Raise a one-line UserError for the first option that is not a positive int."""
    for name, value in values.items():
        if value is not None and value < 1:
            raise UserError(f"--{name.replace('_', '-')} must be at least 1, not {value}")


def _echo(text: str) -> None:
    typer.echo(text)


@data_app.command("synth")
@user_errors(ValueError, FileNotFoundError)
def synth(
    out: Annotated[Path, typer.Option("--out", help="Dataset folder (resumed if it exists).")],
    count: Annotated[int, typer.Option("--count", help="Number of shapes.")],
    seed: Annotated[int, typer.Option("--seed", help="The same seed gives the same bytes.")] = 0,
    style: Annotated[
        str, typer.Option("--style", help="qem, planar, isotropic, quad or farthest.")
    ] = "qem",
    vertices: Annotated[
        str, typer.Option("--vertices", help="Vertex count range MIN:MAX.")
    ] = "128:512",
    points: Annotated[int, typer.Option("--points", help="Points per shape.")] = 2048,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes.")] = 1,
    shard_size: Annotated[int, typer.Option("--shard-size", help="Shapes per shard.")] = 256,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress bar.")
    ] = True,
) -> None:
    """Generate a synthetic CSG dataset in one tessellation style."""
    require_extra("geometry", "synthesising shapes", *SYNTH_MODULES)
    from spacemesh.data.styles import STYLES
    from spacemesh.data.synth import SynthConfig, synthesize

    if style not in STYLES:
        raise UserError(f"unknown --style {style!r}; choose from {', '.join(STYLES)}")
    _positive(count=count, points=points, workers=workers, shard_size=shard_size)
    low, high = parse_vertex_range(vertices)
    config = SynthConfig(
        count=count,
        seed=seed,
        style=style,
        vertex_min=low,
        vertex_max=high,
        points=points,
        shard_size=shard_size,
    )
    manifest = synthesize(config, out, workers=workers, progress=progress)
    counts = manifest["counts"]
    _echo(
        f"{counts['stored']} shapes stored in {out} ({counts['shards']} shards) from "
        f"{counts['attempts']} attempts in {manifest['elapsed_s']:.1f} s"
    )
    _echo(f"splits: {json.dumps(manifest['splits'])}")
    _echo(f"rejections: {json.dumps(manifest['rejections']) if manifest['rejections'] else 'none'}")
    if manifest["failed_indices"]:
        _echo(f"indices given up after every attempt: {manifest['failed_indices']}")


@data_app.command("import")
@user_errors(ValueError, FileNotFoundError)
def import_(
    src_dir: Annotated[Path, typer.Argument(help="Folder of OBJ, OFF, PLY, STL, GLB, glTF files.")],
    out: Annotated[Path, typer.Option("--out", help="Dataset folder.")],
    decimate_to: Annotated[
        int | None,
        typer.Option("--decimate-to", help="QEM-decimate meshes with more vertices."),
    ] = None,
    points: Annotated[int, typer.Option("--points", help="Points per shape.")] = 2048,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the point sampling.")] = 0,
    keep_self_intersecting: Annotated[
        bool,
        typer.Option("--keep-self-intersecting",
                     help="Keep closed manifold meshes whose faces intersect (flagged)."),
    ] = False,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress bar.")
    ] = True,
) -> None:
    """Import a folder of meshes; report every skipped file and why."""
    from spacemesh.data.importer import import_folder

    _positive(points=points)
    if decimate_to is not None and decimate_to < 4:
        raise UserError(f"--decimate-to must be at least 4, not {decimate_to}")
    if not src_dir.is_dir():
        raise UserError(f"{src_dir} is not a folder")
    manifest = import_folder(
        src_dir, out, decimate_to=decimate_to, points=points, seed=seed, progress=progress,
        keep_self_intersecting=keep_self_intersecting,
    )
    kept, skipped = manifest["counts"]["stored"], manifest["skipped"]
    _echo(f"imported {kept} of {kept + len(skipped)} files into {out}")
    for entry in skipped:
        _echo(f"skipped {entry['file']}: {'; '.join(entry['reasons'])}")


@data_app.command("stats")
@user_errors(ValueError, FileNotFoundError)
def stats(
    directory: Annotated[Path, typer.Argument(help="Dataset folder with manifest.json.")],
    png: Annotated[
        Path | None, typer.Option("--png", help="PNG to write (default DIR/stats.png).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
) -> None:
    """Print counts and histograms of a dataset, and write them as a PNG."""
    from spacemesh.data.stats import bar_rows, collect_stats, plot_stats, text_histogram

    data = collect_stats(directory)
    summary = data.summary()
    path = plot_stats(
        data, png or directory / "stats.png", title=f"{directory.name}: {data.count} shapes"
    )
    if as_json:
        _echo(json.dumps({**summary, "png": str(path)}, indent=2))
        return
    _echo(f"{directory}: {data.count} shapes, style {summary['style']}, splits {summary['splits']}")
    _echo(
        f"genus > 0: {summary['fraction_genus_positive']:.1%}, "
        f"concave sharp feature: {summary['fraction_concave_sharp']:.1%}, "
        f"either: {summary['fraction_genus_or_concave']:.1%}"
    )
    if summary["rejections"]:
        _echo(f"rejections ({summary['attempts']} attempts): {json.dumps(summary['rejections'])}")
    for name, rows in (
        ("vertices", text_histogram(data.n_vertices)),
        ("faces", text_histogram(data.n_faces)),
        ("face degrees", bar_rows(dict(data.degrees))),
        ("genus", bar_rows(dict(sorted((int(k), v) for k, v in summary["genus"].items())))),
    ):
        _echo(f"\n{name}:")
        for row in rows:
            _echo(f"  {row}")
    _echo(f"\nwrote {path}")
