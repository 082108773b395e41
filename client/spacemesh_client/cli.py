"""``spacemesh-client``: the service from the command line.

::

    spacemesh-client generate points.ply -o mesh.glb --url http://localhost:8000 --seed 7
    spacemesh-client generate points.ply -o mesh.ply --start points --target-vertices 500 \
        --samples 4
    spacemesh-client repair mesh.obj -o fixed.obj --faces 3,4,10-20
    spacemesh-client repair scan.glb -o fixed.glb --sphere 0,0,1,0.3 --weld
    spacemesh-client health
    spacemesh-client info

The URL comes from ``--url``, else ``$SPACEMESH_URL``, else ``http://localhost:8000``;
``grpc://host:8001`` uses gRPC, ``https://`` and ``grpcs://`` TLS (``--cacert`` for a
private CA). An API key comes from ``--api-key``, else ``$SPACEMESH_API_KEY``. Errors
are one line on stderr (usage mistakes too): exit code 2 for a bad request or a missing
file, 1 when the server or the connection failed (after the retries). Region values may
start with a minus sign (``--sphere -0.5,0,0,0.2``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from spacemesh_client import __version__
from spacemesh_client._formats import MEDIA_TYPES, WRITTEN
from spacemesh_client.client import DEFAULT_FORMAT, DEFAULT_URL, Client
from spacemesh_client.errors import (
    ConnectionFailed,
    InvalidRequest,
    NoSurface,
    SpaceMeshError,
)
from spacemesh_client.mesh import Mesh
from spacemesh_client.options import (
    GENERATE_OPTIONS,
    OPTION_NAMES,
    REPAIR_OPTION_NAMES,
    Option,
)
from spacemesh_client.progress import ProgressBar
from spacemesh_client.retry import RetryPolicy
from spacemesh_client.security import API_KEY_ENV

PROG = "spacemesh-client"
#: Environment variable of the default URL.
URL_ENV = "SPACEMESH_URL"
#: Exit codes.
EXIT_SERVER, EXIT_USAGE = 1, 2


def fail(message: str, code: int = EXIT_USAGE) -> NoReturn:
    """Print one line to stderr and exit."""
    print(f"{PROG}: error: {message}", file=sys.stderr)
    sys.exit(code)


def _numbers(text: str, what: str, count: int) -> list[float]:
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v]
    except ValueError:
        fail(f"--{what}: expected {count} comma-separated numbers, got {text!r}")
    if len(values) != count:
        fail(f"--{what}: expected {count} comma-separated numbers, got {len(values)}")
    return values


def _indices(text: str, what: str) -> list[int]:
    """``1,2,5-9`` -> [1, 2, 5, 6, 7, 8, 9]."""
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


def region_of(args: argparse.Namespace) -> dict[str, Any]:
    """The JSON form of the region given by exactly one region option."""
    given = [name for name in ("faces", "vertices", "sphere", "box", "region")
             if getattr(args, name) is not None]
    if len(given) != 1:
        fail("give exactly one of --faces, --vertices, --sphere, --box, --region")
    kind = given[0]
    text = getattr(args, kind)
    if kind in ("faces", "vertices"):
        return {kind: _indices(text, kind)}
    if kind == "sphere":
        cx, cy, cz, r = _numbers(text, "sphere", 4)
        return {"sphere": {"center": [cx, cy, cz], "radius": r}}
    if kind == "box":
        values = _numbers(text, "box", 6)
        return {"box": {"min": values[:3], "max": values[3:]}}
    try:
        region = json.loads(text)
    except ValueError as error:
        fail(f"--region: not JSON ({error})")
    if not isinstance(region, dict):
        fail("--region: expected a JSON object such as {\"faces\": [1, 2]}")
    return region


def _output_format(output: Path, requested: str | None) -> str:
    """The format to ask the server for: --format, else the output's extension when the
    server writes it, else PLY (converted when saved)."""
    if requested:
        return requested
    suffix = output.suffix.lower().lstrip(".")
    return suffix if suffix in MEDIA_TYPES else DEFAULT_FORMAT


def _check_output(output: Path) -> None:
    suffix = output.suffix.lower().lstrip(".")
    if not suffix:
        fail(f"{output}: give the output an extension ({', '.join(WRITTEN)})")
    if not output.parent.exists():
        fail(f"{output.parent}: no such directory")


def _summary(mesh: Mesh, output: Path, seconds: float) -> dict[str, Any]:
    summary = {"output": str(output), "format": mesh.format, "seed": mesh.seed,
               "steps": mesh.steps, "model": mesh.model, "seconds": round(seconds, 3),
               **mesh.stats.to_dict(), "options": mesh.options}
    if mesh.sample_scores:
        summary["sample_scores"] = [list(item) for item in mesh.sample_scores]
    if mesh.points_reduced is not None:
        summary["points_reduced"] = dict(mesh.points_reduced)
    if mesh.repair is not None:
        summary["repair"] = {k: ({str(d): c for d, c in v.items()} if isinstance(v, dict)
                                 else v) for k, v in mesh.repair.items()}
    return summary


def _report(mesh: Mesh, output: Path, seconds: float, as_json: bool) -> None:
    if as_json:
        print(json.dumps(_summary(mesh, output, seconds)))
        return
    s = mesh.stats
    degrees = ", ".join(f"{k}:{v}" for k, v in sorted(s.face_degrees.items()))
    shape = "closed oriented manifold" if s.closed and s.oriented and s.manifold else (
        "NOT a closed oriented manifold")
    repaired = ""
    if mesh.repair is not None:
        r = mesh.repair
        repaired = (f"; {r.get('region_faces')} faces re-generated ({r.get('grown_faces')} "
                    f"added to the region), {r.get('new_vertices')} new vertices, "
                    f"{r.get('new_faces')} new faces, fallback {r.get('fallback')}")
        if r.get("welded_vertices"):
            repaired += f", {r['welded_vertices']} vertices welded"
    if mesh.points_reduced is not None:  # a big binary cloud, reduced by the server
        print(f"the server used {mesh.points_reduced['used']:,} of the "
              f"{mesh.points_reduced['read']:,} points read", file=sys.stderr)
    print(f"{output}: {s.vertices} vertices, {s.faces} faces ({degrees}), {shape}, "
          f"genus {s.genus}{repaired}; seed {mesh.seed}, {mesh.steps} steps, {mesh.model} "
          f"({seconds:.2f} s){_fit_line(mesh)}")


def _fit_line(mesh: Mesh) -> str:
    """``; fit: points->mesh 0.012, mesh->points 0.010 of the diagonal, coverage 91%; 1 piece,
    genus 0``."""
    fit = mesh.stats.fit
    if not fit:
        return ""
    line = (f"; fit: points->mesh {fit.get('points_to_mesh_mean_rel', float('nan')):.4g}, "
            f"mesh->points {fit.get('mesh_to_points_mean_rel', float('nan')):.4g} of the "
            f"diagonal, coverage {100 * fit.get('coverage', float('nan')):.0f}%")
    if len(mesh.sample_scores) > 1:
        line += f", best of {len(mesh.sample_scores)} seeds"
    if fit.get("tolerance") is not None:
        line += (f", tolerance {fit['tolerance']:g} "
                 f"{'met' if fit.get('tolerance_met') else 'not met'}")
    if "pieces" in fit:  # the fit report's topology (servers from 2026-12 on)
        pieces, loops = int(fit["pieces"]), int(fit.get("boundary_loops", 0))
        points = (f" (the points: {int(fit['points_pieces'])})"
                  if fit.get("points_pieces") is not None else "")
        line += (f"; {pieces} piece{'' if pieces == 1 else 's'}{points}, "
                 f"genus {int(fit['genus'])}")
        line += f", {loops} boundary loop{'' if loops == 1 else 's'}" if loops else ""
    if fit.get("open_surface") is not None:  # servers from 2026-12-06 on
        kind = "open: trimmed to the points" if fit["open_surface"] else "closed"
        line += (f"; {kind} ({100 * float(fit.get('unsupported_area') or 0.0):.0f}% of "
                 "the closed mesh unsupported)")
    if fit.get("points_noise") is not None:  # servers from 2026-12-04 on
        line += f"; the points: noise {100 * fit['points_noise']:.2g}% of the diagonal"
        share = float(fit.get("points_outliers") or 0.0)
        line += f", {100 * share:.2g}% outliers set aside" if share > 0 else ""
    return line


def _save(mesh: Mesh, output: Path) -> None:
    try:
        mesh.save(output)
    except (ModuleNotFoundError, ValueError) as error:
        fail(f"{output}: {error}")


def _client(args: argparse.Namespace) -> Client:
    retry = RetryPolicy(attempts=max(1, args.retries + 1))
    try:
        return Client(args.url, timeout=args.timeout, retry=retry, api_key=args.api_key,
                      verify=args.cacert or True)
    except (ValueError, ModuleNotFoundError) as error:
        fail(str(error))


def cmd_generate(args: argparse.Namespace) -> None:
    output = Path(args.output)
    _check_output(output)
    source = Path(args.input)
    if not source.is_file():
        fail(f"{source}: no such file")
    fmt = _output_format(output, args.format)
    started = time.perf_counter()
    show = sys.stderr.isatty() if args.progress is None else args.progress
    bar = ProgressBar(sys.stderr) if show else None
    try:
        with _client(args) as client:
            mesh = client.generate(source, format=fmt, stage=bar.stage if bar else None,
                                   **{o.name: getattr(args, o.name) for o in GENERATE_OPTIONS})
    finally:
        if bar is not None:
            bar.close()
    _save(mesh, output)
    _report(mesh, output, time.perf_counter() - started, args.json)


def cmd_repair(args: argparse.Namespace) -> None:
    output = Path(args.output)
    _check_output(output)
    source = Path(args.mesh)
    if not source.is_file():
        fail(f"{source}: no such file")
    region = region_of(args)
    fmt = _output_format(output, args.format)
    started = time.perf_counter()
    with _client(args) as client:
        mesh = client.repair(source, region, format=fmt, weld=args.weld,
                             **{name: getattr(args, name) for name in REPAIR_OPTION_NAMES})
    _save(mesh, output)
    _report(mesh, output, time.perf_counter() - started, args.json)


def cmd_health(args: argparse.Namespace) -> None:
    with _client(args) as client:
        health = client.health()
    print(json.dumps({"url": args.url, "live": health.live, "ready": health.ready}))
    if not health.ready:
        sys.exit(EXIT_SERVER)


def cmd_info(args: argparse.Namespace) -> None:
    with _client(args) as client:
        info = client.model_info(args.name)
    print(json.dumps(info, indent=2))


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (``spacemesh-client: error: ...``, exit code 2)."""

    def error(self, message: str) -> NoReturn:
        fail(f"{message} (see {self.prog} --help)")


#: Options whose values may start with "-" (negative coordinates).
_SIGNED_OPTIONS = ("--sphere", "--box")


def _attach_signed_values(argv: Sequence[str]) -> list[str]:
    """``--box -1,-1,-1,1,1,1`` -> ``--box=-1,-1,-1,1,1,1`` (argparse would read the
    value as an option)."""
    out: list[str] = []
    args = list(argv)
    i = 0
    while i < len(args):
        if args[i] in _SIGNED_OPTIONS and i + 1 < len(args) and args[i + 1][:1] == "-" \
                and args[i + 1][1:2] in "0123456789.":
            out.append(f"{args[i]}={args[i + 1]}")
            i += 2
            continue
        out.append(args[i])
        i += 1
    return out


def _add_option_flags(parser: argparse.ArgumentParser, names: Sequence[str]) -> None:
    """A flag per generate option of ``names`` (``--start-time`` for ``start_time``;
    unset: None, the server's default)."""
    group = parser.add_argument_group("generate options")
    for option in GENERATE_OPTIONS:
        if option.name not in names:
            continue
        if option.kind is bool:
            group.add_argument(option.flag, dest=option.name, action="store_const",
                               const=True, default=None, help=option.help)
        else:
            group.add_argument(option.flag, dest=option.name, type=_parser_of(option),
                               metavar=_METAVARS.get(option.kind), help=option.help)


#: The value shown in ``--help`` for an option flag of each type (str: its name).
_METAVARS = {int: "INTEGER", float: "NUMBER"}


def _parser_of(option: Option) -> Callable[[str], Any]:
    """argparse's ``type`` of an option flag: :meth:`Option.parse`, its error as the
    one-line message (``argument --seed: seed must be an integer ...``)."""
    def parse(text: str) -> Any:
        try:
            return option.parse(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    return parse


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (every command takes the connection options)."""
    # the parents are _Parser too: subcommands (of the same class) take only their kind
    common = _Parser(add_help=False)
    connection = common.add_argument_group("connection")
    connection.add_argument("--url", default=os.environ.get(URL_ENV) or DEFAULT_URL,
                            help=f"http(s)://host:port (REST) or grpc://host:port (gRPC); "
                            f"default ${URL_ENV} or {DEFAULT_URL}")
    connection.add_argument("--timeout", type=float, default=300.0,
                            help="seconds one attempt may take (default 300)")
    connection.add_argument("--retries", type=int, default=4,
                            help="retries on connection errors, 503 and 429 (default 4)")
    connection.add_argument("--api-key", default=None,
                            help=f"API key, sent as 'Authorization: Bearer KEY'; default "
                            f"${API_KEY_ENV} (which keeps it out of the process list)")
    connection.add_argument("--cacert", type=Path, default=None,
                            help="PEM file of the CA (or self-signed) certificate that "
                            "https:// and grpcs:// URLs are checked against (default: the "
                            "system's)")
    options = _Parser(add_help=False)
    options.add_argument("-o", "--output", required=True,
                         help=f"output mesh; the extension picks the format ({', '.join(WRITTEN)}"
                         ", or any trimesh writes)")
    options.add_argument("--format", choices=sorted(MEDIA_TYPES),
                         help="format to ask the server for (default: the output's extension)")
    options.add_argument("--json", action="store_true", help="print a JSON summary")

    parser = _Parser(prog=PROG, description="Client of the SpaceMesh service: "
                     "point cloud in, oriented manifold polygon mesh out.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    gen = commands.add_parser("generate", parents=[options, common],
                              help="generate a mesh from a point cloud file")
    gen.add_argument("input", help="point cloud (PLY, XYZ, PTS, TXT, NPY, NPZ, LAS, LAZ, OBJ, ...)")
    _add_option_flags(gen, OPTION_NAMES)
    gen.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="a progress line on stderr (the server's stages and sampler "
                     "steps; default: when stderr is a terminal)")
    gen.set_defaults(run=cmd_generate)

    rep = commands.add_parser("repair", parents=[options, common],
                              help="regenerate a region of a mesh")
    rep.add_argument("mesh", help="mesh file (OBJ, PLY, OFF, STL, GLB, glTF)")
    _add_option_flags(rep, REPAIR_OPTION_NAMES)
    region = rep.add_argument_group("region (exactly one)")
    region.add_argument("--faces", help="face indices, e.g. 3,4,10-20")
    region.add_argument("--vertices", help="vertex indices: every face using one of them")
    region.add_argument("--sphere", help="cx,cy,cz,r: every face with a vertex inside")
    region.add_argument("--box", help="x0,y0,z0,x1,y1,z1: every face with a vertex inside")
    region.add_argument("--region", help='the region as JSON, e.g. {"faces": [1, 2]}')
    rep.add_argument("--weld", action="store_true",
                     help="merge vertices at exactly equal positions first (meshes split at "
                     "UV seams or hard edges, e.g. GLB); region indices stay the file's, the "
                     "output's vertex indices do not")
    rep.set_defaults(run=cmd_repair)

    health = commands.add_parser("health", parents=[common],
                                 help="liveness and readiness (exit 1 when not ready)")
    health.set_defaults(run=cmd_health)

    info = commands.add_parser("info", parents=[common], help="model metadata (REST)")
    info.add_argument("name", nargs="?", help="model name (default: the server's)")
    info.set_defaults(run=cmd_info)
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    """Entry point of ``spacemesh-client``."""
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser().parse_args(_attach_signed_values(argv))
    try:
        args.run(args)
    except ConnectionFailed as error:
        fail(f"{error} (is the server running? `spacemesh serve` starts one)", EXIT_SERVER)
    except NoSurface as error:
        fail(f"{error} (try another --seed)", EXIT_SERVER)
    except InvalidRequest as error:
        fail(str(error), EXIT_USAGE)
    except SpaceMeshError as error:
        fail(str(error), EXIT_SERVER)
    except (OSError, ValueError) as error:
        fail(str(error), EXIT_USAGE)
    except KeyboardInterrupt:
        fail("interrupted", 130)


if __name__ == "__main__":  # pragma: no cover
    main()
