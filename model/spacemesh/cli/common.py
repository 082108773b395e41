"""Shared pieces of the command line: the typer app, one-line error reporting and the
``--threads`` option that every command with threads shares."""

from __future__ import annotations

import sys
from collections.abc import Callable
from functools import wraps
from typing import TYPE_CHECKING, Annotated, Any, NoReturn, ParamSpec, TypeVar

import typer

from spacemesh.threads import default_threads, limit_threads

if TYPE_CHECKING:
    from spacemesh.runtime.options import GenerateOptions

app = typer.Typer(
    name="spacemesh",
    help="SpaceMesh: manifold polygon meshes from continuous per-vertex embeddings.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

#: ``--threads`` of every command (one meaning: :mod:`spacemesh.threads`).
Threads = Annotated[
    int,
    typer.Option(
        "--threads",
        min=0,
        help="CPU threads of torch, the networks and BLAS: exactly N; 0 means one per core "
        f"this process may use ({default_threads()} here). Idle threads sleep, never spin. "
        "The mesh does not depend on it.",
    ),
]

# The generate options of ``spacemesh generate`` and ``spacemesh batch`` (one flag and
# help text each). Values are taken as text and parsed by :func:`generate_options`.
SeedFlag = Annotated[str | None, typer.Option(
    "--seed", metavar="INTEGER", help="The same seed gives the same mesh (default 0).")]
StepsFlag = Annotated[str | None, typer.Option(
    "--steps", metavar="INTEGER", help="Sampler steps (default: the model's).")]
SamplerFlag = Annotated[str | None, typer.Option(
    "--sampler", help="ddim or ddpm (default: the model's).")]
StartFlag = Annotated[str | None, typer.Option(
    "--start", help="Where the vertices start: noise (the paper) or points (chosen on the "
    "input) (default: the model's).")]
StartTimeFlag = Annotated[str | None, typer.Option(
    "--start-time", metavar="NUMBER", help="With --start points: the fraction of the "
    "diffusion to denoise from, 0..1 (0: the chosen points as they are).")]
TargetVerticesFlag = Annotated[str | None, typer.Option(
    "--target-vertices", metavar="INTEGER", help="Vertices of the mesh (within 10%), "
    "4..10,000; needs --start points.")]
ToleranceFlag = Annotated[str | None, typer.Option(
    "--tolerance", metavar="NUMBER", help="The smallest mesh whose mean distance from the "
    "points is at most this fraction of their bounding-box diagonal, 1e-4..0.5 (not with "
    "--target-vertices).")]
SamplesFlag = Annotated[str | None, typer.Option(
    "--samples", metavar="INTEGER", help="Try this many seeds (1..16) from --seed on and "
    "keep the mesh that fits the points best (default 1).")]
RawFlag = Annotated[bool, typer.Option(
    "--raw", help="The networks' mesh without the geometry stage.")]
SurfaceFlag = Annotated[str | None, typer.Option(
    "--surface", metavar="auto|closed|open", help="closed: watertight; open: trimmed to "
    "where the points are (scans seen from some sides only); auto (default): open when the "
    "points leave a large part of the closed mesh unsupported.")]
FaceTypeFlag = Annotated[str | None, typer.Option(
    "--face-type", metavar="triangles|polygons", help="triangles (default), or polygons: "
    "flat regions without interior vertices, merged into planar polygons (fewer vertices "
    "than asked for; OBJ, PLY, OFF keep them; GLB holds triangles).")]

P = ParamSpec("P")
R = TypeVar("R")


class UserError(Exception):
    """An error caused by the user's input; printed as one line, exit code 2."""


def fail(message: str, code: int = 2) -> NoReturn:
    """Print ``spacemesh: error: MESSAGE`` on stderr and exit with ``code``."""
    print(f"spacemesh: error: {message}", file=sys.stderr)
    raise typer.Exit(code)


def option_flag(name: str) -> str:
    """The flag of an option: ``start_time`` -> ``--start-time``."""
    return "--" + name.replace("_", "-")


def generate_options(**values: Any) -> GenerateOptions:
    """Generate options from flag values (text as typed, or None when not given), parsed
    by the service's rule (:meth:`GenerateOptions.parse`); a value of the wrong type is
    one line naming its flag, exit code 2 (``--seed: seed must be an integer ...``).

    Parameters
    ----------
    **values : str, bool or None
        By option name (:data:`~spacemesh.runtime.options.OPTION_FIELDS`).

    Returns
    -------
    GenerateOptions
        Typed, not yet resolved against a model.
    """
    from spacemesh.runtime.options import GenerateOptions, OptionError

    try:
        return GenerateOptions.parse(values)
    except OptionError as error:
        fail(f"{option_flag(error.option)}: {error}")


def option_value(name: str, kind: type, text: str | None) -> Any:
    """One option's flag value parsed by the service's rule
    (:func:`~spacemesh.runtime.options.parse_value`); one line and exit 2 when it is not
    of ``kind``. None when not given."""
    from spacemesh.runtime.options import OptionError, parse_value

    try:
        return parse_value(name, kind, text)
    except OptionError as error:
        fail(f"{option_flag(name)}: {error}")


def require_extra(extra: str, purpose: str, *modules: str) -> None:
    """Exit with one line naming the install command when a module of an extra is missing.

    Parameters
    ----------
    extra : str
        The package extra that installs the modules (``geometry``, ``train``).
    purpose : str
        What needs them (``"synthesising shapes"``), for the message.
    *modules : str
        The modules to import.
    """
    import importlib

    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError:
            fail(f"{purpose} needs the {extra} extra ({name} is missing): "
                 f"pip install 'spacemesh[{extra}]'")


def user_errors(*error_types: type[BaseException]) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """Decorate a command so that the given errors become one-line messages (exit 2)."""
    caught: tuple[type[BaseException], ...] = (UserError, *error_types)

    def decorate(func: Callable[P, R]) -> Callable[P, R]:
        @wraps(func)
        def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
            try:
                return func(*args, **kwargs)
            except caught as error:
                fail(str(error))

        return wrapper

    return decorate


def use_threads(threads: int) -> int:
    """Apply a ``--threads`` value (:func:`spacemesh.threads.limit_threads`); call it
    before the command loads torch, onnxruntime or pymeshlab.

    Returns
    -------
    int
        The thread count in force, to pass on (a model's ``threads``).
    """
    return limit_threads(threads)


class StageBar:
    """One progress line on stderr naming the pipeline stage that is really running:
    ``geometry 1/1 [00:02]``, ``sampler step 12/50 [00:01]``, ``pieces``, ``untangle``,
    ``tolerance 2/6``... Pass :meth:`stage` and :meth:`progress` to
    :meth:`spacemesh.runtime.MeshGenerator.generate`.

    Parameters
    ----------
    enabled : bool
        False draws nothing (``--no-progress``, ``--json``).
    first : str
        What the line says before the first stage (``reading``).
    """

    def __init__(self, enabled: bool, first: str = "starting") -> None:
        from tqdm import tqdm

        self.bar = tqdm(desc=first, bar_format="{desc} [{elapsed}]", disable=not enabled,
                        leave=False)

    def stage(self, name: str, done: int, total: int) -> None:
        """A stage begins (the ``done``-th of ``total``)."""
        if name == "sampler" and total and not done:
            self._show(f"sampler step 0/{total}")
        else:
            self._show(f"{name} {done}/{total}" if total > 1 else name)

    def progress(self, done: int, total: int) -> None:
        """A sampler step finished."""
        self._show(f"sampler step {done}/{total}")

    def _show(self, text: str) -> None:
        self.bar.set_description_str(text, refresh=True)

    def close(self) -> None:
        """Remove the line."""
        self.bar.close()


def fit_progress(bar) -> Callable[[object], None]:
    """A fit's per-step callback that advances the tqdm ``bar`` and shows the step's
    ``loss``, ``edge_f1`` and ``next_accuracy`` (``spacemesh fit`` and
    ``fit-collection``)."""

    def progress(record) -> None:
        bar.update(1)
        bar.set_postfix(
            loss=f"{record.loss:.4f}",
            edge_f1=f"{record.edge_f1:.4f}",
            next_acc=f"{record.next_accuracy:.4f}",
            refresh=False,
        )

    return progress
