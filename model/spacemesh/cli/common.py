"""Shared pieces of the command line: the typer app and one-line error reporting."""

from __future__ import annotations

import sys
from collections.abc import Callable
from functools import wraps
from typing import NoReturn, ParamSpec, TypeVar

import typer

app = typer.Typer(
    name="spacemesh",
    help="SpaceMesh: manifold polygon meshes from continuous per-vertex embeddings.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

P = ParamSpec("P")
R = TypeVar("R")


class UserError(Exception):
    """An error caused by the user's input; printed as one line, exit code 2."""


def fail(message: str, code: int = 2) -> NoReturn:
    """Print ``spacemesh: error: MESSAGE`` on stderr and exit with ``code``."""
    print(f"spacemesh: error: {message}", file=sys.stderr)
    raise typer.Exit(code)


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
    caught = (UserError, *error_types)

    def decorate(func: Callable[P, R]) -> Callable[P, R]:
        @wraps(func)
        def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
            try:
                return func(*args, **kwargs)
            except caught as error:
                fail(str(error))

        return wrapper

    return decorate
