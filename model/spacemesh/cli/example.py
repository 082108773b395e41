"""``spacemesh example``: write one of the built-in example meshes."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from spacemesh.cli.common import app, fail
from spacemesh.examples import EXAMPLES


@app.command()
def example(
    name: Annotated[str, typer.Argument(help=f"One of: {', '.join(EXAMPLES)}.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="Mesh file to write.")],
) -> None:
    """Write a built-in example mesh (quads, n-gons, a mixed torus, a sphere)."""
    from spacemesh.io import save_mesh
    from spacemesh.io.errors import MeshFormatError

    if name not in EXAMPLES:
        fail(f"unknown example {name!r}; choose one of: {', '.join(EXAMPLES)}")
    if not output.parent.exists():
        fail(f"{output.parent}: no such directory")
    mesh = EXAMPLES[name]()
    try:
        save_mesh(mesh, output)
    except MeshFormatError as error:
        fail(str(error))
    typer.echo(f"wrote {output}: {mesh.n_vertices} vertices, {mesh.n_faces} faces")
