"""The ``spacemesh`` command line: fit, data, train, export, eval, generate, repair, serve,
batch.

Each command group lives in its own module and registers itself on :data:`app`.
Errors a user can cause are printed as one line on stderr with exit code 2.
"""

from __future__ import annotations

import importlib

from spacemesh.cli.common import app

#: Modules that add commands to ``app``; optional ones may be missing in slim installs.
COMMAND_MODULES = (
    "spacemesh.cli.example",
    "spacemesh.cli.fit",
    "spacemesh.cli.fit_collection",
    "spacemesh.cli.data",
    "spacemesh.cli.train",
    "spacemesh.cli.evaluate",
    "spacemesh.cli.generate",
    "spacemesh.cli.repair",
    "spacemesh.cli.serve",
    "spacemesh.cli.batch",
)


def _register() -> None:
    for name in COMMAND_MODULES:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as error:
            if error.name != name:  # the module exists but one of its imports is missing
                raise


def main() -> None:
    """Entry point of the ``spacemesh`` console script."""
    _register()
    app()


__all__ = ["app", "main"]
