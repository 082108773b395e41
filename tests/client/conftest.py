"""Fixtures of the client tests: real servers on loopback, as in tests/service.

The tiny exported model and the server fixtures are those of ``tests/service/conftest.py``,
imported rather than copied (``toy_repository``, ``generator``, ``case``,
``start_server``, ``server``). That conftest imports its helpers as the top-level module
``service_testing`` (pytest puts ``tests/service`` on ``sys.path`` when it loads it), so
the folder is put there first: these tests may run before or without tests/service.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SERVICE_TESTS = Path(__file__).resolve().parents[1] / "service"
#: The client tests need the SDK and a real server.
DEPENDENCIES = ("httpx", "grpc", "fastapi", "uvicorn", "grpc_health", "spacemesh_service",
                "spacemesh_client")
if not all(importlib.util.find_spec(name) for name in DEPENDENCIES):
    collect_ignore_glob = ["test_*.py"]
else:
    if str(SERVICE_TESTS) not in sys.path:
        sys.path.insert(0, str(SERVICE_TESTS))
    from tests.service.conftest import (  # noqa: F401  (fixtures)
        case,
        generator,
        server,
        start_server,
        toy_repository,
    )


@pytest.fixture(scope="session")
def rest_url(server) -> str:
    """``http://127.0.0.1:PORT`` of the shared server."""
    return server.url


@pytest.fixture(scope="session")
def grpc_url(server) -> str:
    """``grpc://127.0.0.1:PORT`` of the shared server."""
    return "grpc://" + server.grpc_target


@pytest.fixture(params=["rest", "grpc"])
def url(request, rest_url, grpc_url) -> str:
    """Each transport's URL of the shared server, in turn."""
    return rest_url if request.param == "rest" else grpc_url


@pytest.fixture
def client(url):
    """A client of the shared server that fails at once (no retries)."""
    from spacemesh_client import Client, RetryPolicy

    with Client(url, timeout=60, retry=RetryPolicy.never()) as c:
        yield c
