"""``spacemesh generate``: a point cloud in, a manifold polygon mesh out (onnxruntime only).

The generate options are :class:`spacemesh.runtime.options.GenerateOptions`, one flag
each (``--start-time`` for ``start_time``), read as text and parsed by the service's rule
(:meth:`GenerateOptions.parse`: ``--seed 1e3`` is refused, not converted); the generator
resolves them once, and an option of the wrong type or out of range is one line on stderr
and exit code 2. The input is read
and checked as the service and ``spacemesh batch`` read it
(:func:`spacemesh.runtime.cloud.read_generate_input`, with the service's default limits):
too few or too many points, NaN or infinite values, or identical, collinear or coplanar
points are one line on stderr and exit code 2. A cloud of more than
:data:`~spacemesh.io.reduce.DEFAULT_WORKING_POINTS` points is first reduced to that many
(a seeded random subset, as the service does; ``points_reduced`` in the summary says from
how many). The summary reports the resolved options, the fit report
(:meth:`FitReport.to_dict`) and every seed's score. With ``--budget-s`` or ``--budget-mb``
the request's cost is estimated first (:mod:`spacemesh.runtime.cost`, the service's check):
one over the budget is one line naming the option to lower (``too-expensive``) and exit
code 2, before any work.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from spacemesh.cli.common import (
    FaceTypeFlag,
    RawFlag,
    SamplerFlag,
    SamplesFlag,
    SeedFlag,
    StageBar,
    StartFlag,
    StartTimeFlag,
    StepsFlag,
    SurfaceFlag,
    TargetVerticesFlag,
    Threads,
    ToleranceFlag,
    app,
    fail,
    generate_options,
    option_flag,
    use_threads,
)

MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".off")


@app.command()
def generate(
    points_path: Annotated[
        Path, typer.Argument(metavar="POINTS", help="Point cloud (PLY, XYZ, NPY, NPZ, "
                             "LAS, LAZ ...), "
                             "or a mesh (OBJ, OFF, PLY, STL, GLB/glTF with faces), whose "
                             "surface is sampled.")
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", help="Mesh file: .glb, .gltf, .obj, .ply or .off.")
    ],
    model: Annotated[
        Path | None,
        typer.Option("--model", help="Model repository (default: the shipped model or "
                                     "$SPACEMESH_MODEL)."),
    ] = None,
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
    threads: Threads = 0,
    budget_s: Annotated[float | None, typer.Option(
        "--budget-s", min=0, help="Refuse the request (exit 2) when its estimated time "
        "(seconds on the 2-core reference machine) is over this, before any work; the "
        "service's check (spacemesh serve --request-budget-s).")] = None,
    budget_mb: Annotated[float | None, typer.Option(
        "--budget-mb", min=0, help="Refuse the request (exit 2) when its estimated peak "
        "memory (MB) is over this.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary.")] = False,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress bar.")
    ] = True,
) -> None:
    """Generate a mesh of the surface sampled by POINTS."""
    from spacemesh.io import save_mesh
    from spacemesh.io.errors import MeshFormatError
    from spacemesh.runtime import MeshGenerator, ModelRepositoryError
    from spacemesh.runtime.cloud import CloudError, read_generate_input
    from spacemesh.runtime.options import OptionError

    options = generate_options(seed=seed, steps=steps, sampler=sampler, start=start,
                               start_time=start_time, target_vertices=target_vertices,
                               tolerance=tolerance, samples=samples, raw=raw,
                               surface=surface, face_type=face_type)
    if output.suffix.lower() not in MESH_SUFFIXES:
        fail(f"{output}: the output must end in one of {', '.join(MESH_SUFFIXES)}")
    if not output.parent.exists():
        fail(f"{output.parent}: no such directory")
    if not points_path.is_file():
        fail(f"{points_path}: no such file")
    try:
        generator = MeshGenerator.from_repository(model, threads=use_threads(threads))
    except ModelRepositoryError as error:
        fail(str(error))
    try:  # a mesh's surface is sampled to the model's point count, a big cloud reduced
        cloud = read_generate_input(points_path, n_points=generator.spec.n_points,
                                    needs_normals=generator.spec.normals)
    except MeshFormatError as error:
        fail(f"{points_path}: {error}")
    except CloudError as error:
        fail(f"{points_path}: {error} ({error.kind})")
    points, normals = cloud.points, cloud.normals
    if budget_s is not None or budget_mb is not None:
        _check_budget(generator, options, len(points), budget_s, budget_mb, points_path)
    bar = StageBar(progress and not as_json)
    try:
        result = generator.generate(points, normals, options, progress=bar.progress,
                                    stage=bar.stage)
    except OptionError as error:
        fail(f"{option_flag(error.option)}: {error}")
    except ValueError as error:
        fail(str(error))
    finally:
        bar.close()
    save_mesh(result.mesh, output)
    if result.mesh.n_faces == 0:
        typer.echo("spacemesh: warning: the model produced an empty mesh", err=True)
    fit = result.fit.to_dict() if result.fit is not None else {}
    summary = {
        "output": str(output), "model": generator.name, "input": cloud.kind,
        **result.options.to_dict(),
        "vertices": result.mesh.n_vertices, "faces": result.mesh.n_faces, "fit": fit,
        "sample_scores": [[s, score] for s, score in result.sample_scores],
        "timings": {k: round(v, 4) for k, v in result.timings.items()},
    }
    if cloud.count is not None:  # a big cloud, reduced to the working size
        summary["points_reduced"] = {"read": cloud.count, "used": len(cloud.points)}
        if not as_json:
            typer.echo(f"spacemesh: {points_path}: {cloud.count} points, reduced to "
                       f"{len(cloud.points)} (a seeded random subset)", err=True)
    if as_json:
        typer.echo(json.dumps(summary))
    else:
        typer.echo(f"{output}: {result.mesh.n_vertices} vertices, {result.mesh.n_faces} faces, "
                   f"seed {result.seed}, start {result.options.start} "
                   f"({result.timings['total']:.2f} s); fit: points->mesh "
                   f"{fit.get('points_to_mesh_mean_rel', float('nan')):.4g}, mesh->points "
                   f"{fit.get('mesh_to_points_mean_rel', float('nan')):.4g} of the diagonal, "
                   f"coverage {100 * fit.get('coverage', float('nan')):.0f}%"
                   f"{_tolerance_text(fit)}{_topology_text(fit)}{_surface_text(fit)}"
                   f"{_points_text(fit)}")


def _check_budget(generator: Any, options: Any, points: int, seconds: float | None,
                  memory_mb: float | None, path: Path) -> None:
    """Exit 2 with one line when the request's estimated cost is over the budget."""
    from spacemesh.runtime.budget import Budget, CostError
    from spacemesh.runtime.cost import DEFAULT_COST_MODEL
    from spacemesh.runtime.options import OptionError

    try:
        resolved = options.resolve(generator.spec)
    except OptionError as error:
        fail(f"{option_flag(error.option)}: {error}")
    estimate = DEFAULT_COST_MODEL.generate(generator.spec, resolved, points)
    try:
        Budget(seconds, memory_mb).check(estimate, what="generate")
    except CostError as error:
        fail(f"{path}: {error} ({error.kind})")


def _tolerance_text(fit: dict) -> str:
    """``, tolerance 0.005 met`` (or ``not met``) from a fit report ("" without one)."""
    if fit.get("tolerance") is None:
        return ""
    return f", tolerance {fit['tolerance']:g} {'met' if fit.get('tolerance_met') else 'not met'}"


def _surface_text(fit: dict) -> str:
    """``; open: trimmed to the points (31% of the closed mesh unsupported)`` (or
    ``closed``) from a fit report ("" without the decision: ``--raw``)."""
    if fit.get("open_surface") is None:
        return ""
    share = 100 * float(fit.get("unsupported_area") or 0.0)
    kind = "open: trimmed to the points" if fit["open_surface"] else "closed"
    return f"; {kind} ({share:.0f}% of the closed mesh unsupported)"


def _points_text(fit: dict) -> str:
    """``; the points: noise 0.45% of the diagonal, 4.8% outliers set aside`` from a fit
    report ("" without the points' estimates; the outliers only when some were)."""
    if fit.get("points_noise") is None:
        return ""
    text = f"; the points: noise {100 * fit['points_noise']:.2g}% of the diagonal"
    share = float(fit.get("points_outliers") or 0.0)
    return text + (f", {100 * share:.2g}% outliers set aside" if share > 0 else "")


def _topology_text(fit: dict) -> str:
    """``; 1 piece (the points: 1), genus 1`` (and the boundary loops of an open mesh)
    from a fit report."""
    if "pieces" not in fit:
        return ""
    pieces = int(fit["pieces"])
    points = (f" (the points: {int(fit['points_pieces'])})"
              if fit.get("points_pieces") is not None else "")
    text = f"; {pieces} piece{'' if pieces == 1 else 's'}{points}, genus {int(fit['genus'])}"
    loops = int(fit.get("boundary_loops", 0))
    return text + (f", {loops} boundary loop{'' if loops == 1 else 's'}" if loops else "")
