"""``spacemesh repair``: re-generate a marked region of a mesh (onnxruntime only).

``--seed``, ``--steps``, ``--sampler`` and ``--max-growth`` are read as text and parsed
and checked as the service checks ``/repair``'s options
(:meth:`~spacemesh.runtime.options.GenerateOptions.parse`, then
:meth:`~spacemesh.runtime.options.GenerateOptions.resolve`): a value of the wrong type or
out of range is one line and exit code 2.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from spacemesh.cli.common import (
    Threads,
    app,
    fail,
    generate_options,
    option_flag,
    option_value,
    use_threads,
)

MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".off")
#: The repair the command runs: None for :func:`spacemesh.repair.repair_mesh` (the tests
#: put a faulty one here to check that a faulty repair is never written).
REPAIR: Callable[..., Any] | None = None


def _numbers(text: str, what: str, count: int | None = None) -> list[float]:
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v]
    except ValueError:
        fail(f"--{what}: expected comma-separated numbers, got {text!r}")
    if count is not None and len(values) != count:
        fail(f"--{what}: expected {count} numbers, got {len(values)}")
    return values


def _indices(text: str, what: str) -> list[int]:
    out: list[int] = []
    for part in text.replace(" ", "").split(","):
        if not part:
            continue
        try:
            if "-" in part[1:]:
                lo, hi = part.split("-", 1)
                out.extend(range(int(lo), int(hi) + 1))
            else:
                out.append(int(part))
        except ValueError:
            fail(f"--{what}: expected indices like 1,2,5-9, got {part!r}")
    return out


def region_from_options(faces: str | None, vertices: str | None, sphere: str | None,
                        box: str | None, *, holes: bool = False, defects: bool = False,
                        auto: bool = False) -> dict:
    """The JSON form of the region given by exactly one of the four options, or the
    automatic region of ``--holes``, ``--defects`` or ``--auto`` (both; ``--holes
    --defects`` is the same)."""
    given = [(k, v) for k, v in (("faces", faces), ("vertices", vertices), ("sphere", sphere),
                                 ("box", box)) if v is not None]
    if holes or defects or auto:
        if given:
            fail("--holes, --defects and --auto find the region themselves; they do not "
                 f"combine with --{given[0][0]}")
        return {"auto": "all" if auto or (holes and defects) else
                "holes" if holes else "defects"}
    if len(given) != 1:
        fail("give exactly one of --faces, --vertices, --sphere, --box (or --holes, "
             "--defects, --auto)")
    kind, text = given[0]
    if kind in ("faces", "vertices"):
        return {kind: _indices(text, kind)}
    if kind == "sphere":
        cx, cy, cz, r = _numbers(text, "sphere", 4)
        return {"sphere": {"center": [cx, cy, cz], "radius": r}}
    values = _numbers(text, "box", 6)
    return {"box": {"min": values[:3], "max": values[3:]}}


def auto_summary(stats: Any) -> str:
    """What an automatic repair found and did, in a few words."""
    kinds: dict[str, int] = {}
    for finding in stats.findings:
        kinds[finding["kind"]] = kinds.get(finding["kind"], 0) + 1
    found = ", ".join(f"{n} {k}" for k, n in kinds.items()) or "nothing"
    by_fan = sum(1 for f in stats.findings if f.get("filled_by", "model") != "model")
    return (f"found {found} ({stats.findings_total} in all), {stats.passes} passes"
            + (f", {by_fan} holes partly filled by the fallback fan" if by_fan else "")
            + (f", {stats.reversed_faces} faces reoriented" if stats.reversed_faces else ""))


def crossings_summary(stats: Any) -> str:
    """What the repair did about faces that crossed (docs/REPAIR.md, "Limits"): ``""``
    when nothing, else e.g. ``", 12 faces made again and 3 taken in where the new faces
    crossed"``, or that they still cross when growing the region did not mend them."""
    fill = stats.fill
    again = int(fill.get("refilled_faces", 0))
    taken = int(fill.get("regrown_faces", 0))
    if not (again or taken):  # a region grown and repaired again, not kept: still crossing
        return (", new faces still cross (the region grown around them did not mend them)"
                if fill.get("regrowths", 0) else "")
    parts = ([f"{again} faces made again"] if again else []) + [f"{taken} taken in"]
    return ", " + " and ".join(parts) + " where the new faces crossed"


@app.command()
def repair(
    mesh_path: Annotated[Path, typer.Argument(metavar="MESH", help="Mesh file (OBJ, PLY, "
                                              "OFF, STL, GLB, glTF).")],
    output: Annotated[
        Path, typer.Option("-o", "--output", help="Mesh file: .glb, .gltf, .obj, .ply or .off.")
    ],
    faces: Annotated[str | None, typer.Option(
        "--faces", help="Face indices, e.g. 3,4,10-20.")] = None,
    vertices: Annotated[str | None, typer.Option(
        "--vertices", help="Vertex indices: every face using one of them.")] = None,
    sphere: Annotated[str | None, typer.Option(
        "--sphere", help="cx,cy,cz,r: every face with a vertex inside.")] = None,
    box: Annotated[str | None, typer.Option(
        "--box", help="x0,y0,z0,x1,y1,z1: every face with a vertex inside.")] = None,
    holes: Annotated[bool, typer.Option(
        "--holes", help="Fill every hole (boundary loop) with the ring of faces around it.")
    ] = False,
    defects: Annotated[bool, typer.Option(
        "--defects", help="Rebuild every non-manifold edge or vertex and degenerate face "
        "with its neighbourhood.")] = False,
    auto: Annotated[bool, typer.Option("--auto", help="--holes and --defects.")] = False,
    max_growth: Annotated[str | None, typer.Option(
        "--max-growth", metavar="NUMBER", help="Largest share of the faces a region may grow "
        "to (default 0.25).")] = None,
    weld: Annotated[bool, typer.Option(
        "--weld", help="Merge vertices at exactly equal positions first (meshes split at UV "
        "seams or hard edges, e.g. GLB); --vertices are the file's indices.")] = False,
    model: Annotated[Path | None, typer.Option(
        "--model", help="Model repository (default: the shipped model or $SPACEMESH_MODEL).")
    ] = None,
    seed: Annotated[str | None, typer.Option(
        "--seed", metavar="INTEGER", help="The same seed gives the same mesh (default 0).")
    ] = None,
    steps: Annotated[str | None, typer.Option(
        "--steps", metavar="INTEGER", help="Sampler steps (default: the model's).")] = None,
    sampler: Annotated[str | None, typer.Option(
        "--sampler", help="ddim or ddpm (default: the model's).")] = None,
    threads: Threads = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON summary.")] = False,
    progress: Annotated[bool, typer.Option(
        "--progress/--no-progress", help="Progress bar.")] = True,
) -> None:
    """Re-generate the vertices and faces of a region of MESH; the rest stays unchanged."""
    from tqdm import tqdm

    from spacemesh.io import load_mesh, save_mesh
    from spacemesh.io.errors import MeshFormatError
    from spacemesh.repair import RegionError, plan_repair, repair_mesh, verify_repair
    from spacemesh.runtime import MeshGenerator, ModelRepositoryError
    from spacemesh.runtime.options import OptionError

    options = generate_options(seed=seed, steps=steps, sampler=sampler)
    growth = option_value("max_growth", float, max_growth)
    if growth is not None and not 0.0 <= growth <= 1.0:  # NaN fails too
        fail(f"--max-growth: max_growth must be in 0..1, not {growth}")
    if output.suffix.lower() not in MESH_SUFFIXES:
        fail(f"{output}: the output must end in one of {', '.join(MESH_SUFFIXES)}")
    if not output.parent.exists():
        fail(f"{output.parent}: no such directory")
    if not mesh_path.is_file():
        fail(f"{mesh_path}: no such file")
    region = region_from_options(faces, vertices, sphere, box, holes=holes, defects=defects,
                                 auto=auto)
    try:
        mesh = load_mesh(mesh_path)
    except MeshFormatError as error:
        fail(f"{mesh_path}: {error}")
    try:
        generator = MeshGenerator.from_repository(model, threads=use_threads(threads))
    except ModelRepositoryError as error:
        fail(str(error))
    try:
        chosen = options.resolve(generator.spec)  # ranges, as the service checks them
    except OptionError as error:
        fail(f"{option_flag(error.option)}: {error}")
    try:
        plan = plan_repair(mesh, region, generator.spec.max_vertices, weld=weld,
                           max_growth=growth)
    except RegionError as error:
        fail(f"{error.kind}: {error}")
    bar = tqdm(desc="inpainting", unit="step", disable=not progress or as_json, leave=False)

    def report(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    try:
        run: Callable[..., Any] = repair_mesh if REPAIR is None else REPAIR
        result = run(mesh, region, generator, seed=chosen.seed, steps=chosen.steps,
                     method=chosen.sampler, progress=report, plan=plan, weld=weld)
    except ValueError as error:
        fail(str(error))
    finally:
        bar.close()
    issues = verify_repair(plan, result)
    if issues:  # the service's check: a faulty repair is never written
        fail("internal error: the repair changed the mesh outside the grown region: "
             + "; ".join(issues), code=1)
    save_mesh(result.mesh, output)
    stats = result.stats
    if as_json:
        summary = {"output": str(output), "model": generator.name,
                   "vertices": result.mesh.n_vertices, "faces": result.mesh.n_faces,
                   **stats.to_dict()}
        summary["timings"] = {k: round(v, 4) for k, v in stats.timings.items()}
        typer.echo(json.dumps(summary))
    else:
        typer.echo(
            f"{output}: {stats.region_faces} faces re-generated ({stats.grown_faces} added "
            f"to the region), {stats.new_vertices} new vertices, {stats.new_faces} new faces, "
            f"fallback {stats.fallback}"
            + (f", {stats.welded_vertices} vertices welded" if weld else "")
            + (f", {auto_summary(stats)}" if stats.auto_region else "")
            + crossings_summary(stats)
            + f" ({stats.timings['total']:.2f} s)"
        )
