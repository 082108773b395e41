"""``spacemesh serve``: the REST and gRPC servers in one process (the ``service/`` package).

The flags are made from the fields of :class:`spacemesh_service.settings.Settings`, one
per field, each with its environment variable (``--grpc-port`` / ``SPACEMESH_GRPC_PORT``),
so the service has one list of settings. The service is imported lazily: without it
(``pip install -e service``) the command prints one line and exits 2.
"""

from __future__ import annotations

import inspect
import sys
from pathlib import Path
from typing import Any, Optional, get_args

import typer

from spacemesh.cli.common import app, fail

_HELP = """Serve the model over REST (uvicorn) and gRPC.

Every flag has an environment variable of the same name (SPACEMESH_*); a flag wins.
The model is the shipped models/spacemesh-small unless --model names another repository.
"""


def _settings_class() -> Any:
    try:
        from spacemesh_service.settings import Settings
    except ModuleNotFoundError as error:
        missing = error.name or "spacemesh_service"
        what = ("the service package is not installed" if missing.startswith("spacemesh_service")
                else f"the service needs {missing}, which is not installed")
        fail(f"{what}: pip install -e service")
    return Settings


def _option_type(annotation: Any) -> type:
    """``int | None`` -> ``int``; Path stays Path."""
    args = [a for a in get_args(annotation) if a is not type(None)]
    return args[0] if args else annotation


def _flag(name: str, kind: type) -> str:
    flag = "--" + name.replace("_", "-")
    return f"{flag}/--no-{name.replace('_', '-')}" if kind is bool else flag


def _serve(**flags: Any) -> None:
    Settings = _settings_class()
    try:
        settings = Settings.from_env(**flags)
    except ValueError as error:
        fail(str(error))
    from spacemesh.runtime.repository import default_model_dir

    model = Path(settings.model) if settings.model is not None else default_model_dir()
    if not model.exists():
        hint = "" if settings.model is not None else " (the shipped model; pass --model DIR)"
        fail(f"model repository {model} does not exist{hint}")
    try:
        from spacemesh_service.server import run
    except ModuleNotFoundError as error:
        fail(f"the service needs {error.name}, which is not installed: pip install -e service")
    sys.exit(run(settings))


def _register() -> None:
    """Add ``serve`` to the app, with one option per settings field."""
    try:
        from spacemesh_service.settings import Settings
    except ModuleNotFoundError:  # register a stub that explains what to install
        @app.command(name="serve", help=_HELP)
        def serve_stub() -> None:
            _settings_class()

        return
    parameters = []
    for name, field in Settings.model_fields.items():
        kind = _option_type(field.annotation)
        option = typer.Option(None, _flag(name, kind), envvar=Settings.env_name(name),
                              help=field.description, show_envvar=True)
        parameters.append(inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY,
                                            default=option, annotation=Optional[kind]))  # noqa: UP045

    def serve(**flags: Any) -> None:
        _serve(**flags)

    serve.__signature__ = inspect.Signature(parameters)  # type: ignore[attr-defined]
    serve.__annotations__ = {p.name: p.annotation for p in parameters}
    app.command(help=_HELP)(serve)


_register()
