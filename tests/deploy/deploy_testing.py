"""Helpers of the deployment tests: paths, check tools, and a fresh runtime environment."""

from __future__ import annotations

import os
import shutil
import socket
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: The tools of deploy/requirements-check.txt.
CHECK_REQUIREMENTS = ROOT / "deploy" / "requirements-check.txt"


def missing(what: str) -> None:
    """Skip for lack of a check tool; in CI (``CI`` set) fail, so a check never silently
    stops running."""
    message = f"{what} is not installed: pip install -r {CHECK_REQUIREMENTS.relative_to(ROOT)}"
    if os.environ.get("CI"):
        pytest.fail(message)
    pytest.skip(message)


def executable(name: str) -> str | None:
    """A command next to this Python (a venv's bin/), else on PATH."""
    here = Path(sys.executable).parent / name
    return str(here) if here.is_file() else shutil.which(name)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
