"""``spacemesh fit``: encode one mesh by direct optimisation of its embeddings."""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from spacemesh.cli.common import Threads, app, fail, fit_progress, use_threads
from spacemesh.errors import SpaceMeshError


class DistanceChoice(str, Enum):
    """Adjacency distances (paper Fig. 6)."""

    spacetime = "spacetime"
    euclidean = "euclidean"
    dot = "dot"


class ReductionChoice(str, Enum):
    """Permutation reductions (paper Fig. 7)."""

    product = "product"
    sum = "sum"
    max = "max"
    concat = "concat"


class InitChoice(str, Enum):
    """Initial adjacency embeddings."""

    random = "random"
    positions = "positions"


@app.command()
def fit(
    mesh_path: Annotated[Path, typer.Argument(metavar="MESH", help="Closed manifold mesh file.")],
    output: Annotated[
        Path | None, typer.Option("-o", "--output", help="Write the decoded mesh here.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    distance: Annotated[DistanceChoice, typer.Option(help="Adjacency distance.")] = (
        DistanceChoice.spacetime
    ),
    reduction: Annotated[ReductionChoice, typer.Option(help="Permutation reduction.")] = (
        ReductionChoice.product
    ),
    init: Annotated[
        InitChoice,
        typer.Option(help="Start from random embeddings (the paper) or from the vertex "
                     "positions (about 2x fewer iterations; spacetime and euclidean only)."),
    ] = InitChoice.random,
    max_iters: Annotated[int, typer.Option(min=1, help="Iteration budget.")] = 1000,
    seed: Annotated[int, typer.Option(help="Random seed of the initial embeddings.")] = 0,
    threads: Threads = 0,
) -> None:
    """Fit SpaceMesh embeddings to MESH until they decode to it exactly.

    Exit code 0 when the decode is exact, 1 when the budget ran out, 2 on bad input.
    """
    from spacemesh.io import load_mesh, save_mesh
    from spacemesh.io.errors import MeshFormatError

    if init is InitChoice.positions and distance is DistanceChoice.dot:
        fail("--init positions needs a distance with space coordinates (spacetime, euclidean)")
    if not mesh_path.is_file():
        fail(f"{mesh_path}: no such file")
    if output is not None and not output.parent.exists():
        fail(f"{output.parent}: no such directory")
    try:
        mesh = load_mesh(mesh_path)
    except MeshFormatError as error:
        fail(f"{mesh_path}: {error}")

    threads = use_threads(threads)  # before torch loads
    try:
        from spacemesh.fitting import EmbeddingFitConfig, fit_mesh
    except ModuleNotFoundError as error:
        fail(
            f"fitting needs the training extra ({error.name} is missing): "
            "pip install 'spacemesh[train]'"
        )
    from tqdm import tqdm

    from spacemesh.encode import require_closed_manifold

    try:  # before the progress bar, so that a refusal is one line
        require_closed_manifold(mesh)
    except SpaceMeshError as error:
        fail(f"{mesh_path}: {error}")
    config = EmbeddingFitConfig(
        distance=distance.value,
        reduction=reduction.value,
        max_iters=max_iters,
        seed=seed,
        threads=threads,
        init=init.value,
    )
    bar = tqdm(total=max_iters, desc="fit", unit="it", disable=as_json, leave=False)
    progress = fit_progress(bar)

    try:
        result = fit_mesh(mesh, config, progress)
    except SpaceMeshError as error:
        bar.close()
        fail(f"{mesh_path}: {error}")
    bar.close()
    if output is not None:
        assert result.decoded is not None  # fit_mesh always decodes
        save_mesh(result.decoded.mesh, output)
    summary = result.summary()
    if as_json:
        typer.echo(json.dumps(summary))
    else:
        status = "exact" if result.exact else "NOT exact"
        typer.echo(
            f"{mesh_path.name}: {status} after {result.iterations} iterations "
            f"({result.seconds:.1f} s), {result.n_vertices} vertices, {result.n_faces} faces, "
            f"edge F1 {result.edge_f1:.4f}, next accuracy {result.next_accuracy:.4f}"
        )
        if output is not None:
            typer.echo(f"wrote {output}")
    raise typer.Exit(0 if result.exact else 1)
