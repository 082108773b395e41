"""``spacemesh generate``: a point cloud in, a manifold polygon mesh out (onnxruntime only)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from spacemesh.cli.common import app, fail

MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".off")


@app.command()
def generate(
    points_path: Annotated[
        Path, typer.Argument(metavar="POINTS", help="Point cloud (PLY, XYZ, NPY, NPZ ...).")
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", help="Mesh file: .glb, .gltf, .obj, .ply or .off.")
    ],
    model: Annotated[
        Path | None,
        typer.Option("--model", help="Model repository (default: the shipped model or "
                                     "$SPACEMESH_MODEL)."),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="The same seed gives the same mesh.")] = 0,
    steps: Annotated[
        int | None, typer.Option("--steps", min=1, help="Sampler steps (default: the model's).")
    ] = None,
    sampler: Annotated[
        str | None, typer.Option("--sampler", help="ddim or ddpm (default: the model's).")
    ] = None,
    threads: Annotated[
        int, typer.Option("--threads", min=0, help="onnxruntime threads (0: all).")
    ] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary.")] = False,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress bar.")
    ] = True,
) -> None:
    """Generate a mesh of the surface sampled by POINTS."""
    from tqdm import tqdm

    from spacemesh.io import save_mesh
    from spacemesh.io.errors import MeshFormatError
    from spacemesh.io.points import load_points
    from spacemesh.runtime import MeshGenerator, ModelRepositoryError

    if output.suffix.lower() not in MESH_SUFFIXES:
        fail(f"{output}: the output must end in one of {', '.join(MESH_SUFFIXES)}")
    if not output.parent.exists():
        fail(f"{output.parent}: no such directory")
    if not points_path.is_file():
        fail(f"{points_path}: no such file")
    try:
        points, normals = load_points(points_path)
    except MeshFormatError as error:
        fail(f"{points_path}: {error}")
    try:
        generator = MeshGenerator.from_repository(model, intra_op_threads=threads)
    except ModelRepositoryError as error:
        fail(str(error))
    bar = tqdm(desc="diffusion", unit="step", disable=not progress or as_json, leave=False)

    def report(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    try:
        result = generator.generate(points, normals, seed=seed, steps=steps, method=sampler,
                                    progress=report)
    except ValueError as error:
        fail(str(error))
    finally:
        bar.close()
    save_mesh(result.mesh, output)
    if result.mesh.n_faces == 0:
        typer.echo("spacemesh: warning: the model produced an empty mesh", err=True)
    summary = {
        "output": str(output), "model": generator.name, "seed": result.seed,
        "steps": result.steps, "sampler": result.method, "vertices": result.mesh.n_vertices,
        "faces": result.mesh.n_faces,
        "timings": {k: round(v, 4) for k, v in result.timings.items()},
    }
    if as_json:
        typer.echo(json.dumps(summary))
    else:
        typer.echo(f"{output}: {result.mesh.n_vertices} vertices, {result.mesh.n_faces} faces "
                   f"({result.timings['total']:.2f} s)")
