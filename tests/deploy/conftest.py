"""Fixtures of the deployment tests: what cannot run here (no Docker engine) is checked
with the tools that can, and the runtime image's environment is built for real.

The tiny exported model and the server fixtures are those of ``tests/service/conftest.py``,
imported rather than copied (see ``tests/client/conftest.py`` for why ``tests/service``
goes on ``sys.path``).
"""

from __future__ import annotations

import importlib.util
import sys

import pytest
from deploy_testing import ROOT, missing

SERVICE_TESTS = ROOT / "tests" / "service"

if str(SERVICE_TESTS) not in sys.path:
    sys.path.insert(0, str(SERVICE_TESTS))
if importlib.util.find_spec("spacemesh_service") and importlib.util.find_spec("grpc_health"):
    from tests.service.conftest import (  # noqa: F401  (fixtures)
        case,
        generator,
        start_server,
        toy_repository,
    )


@pytest.fixture(scope="session")
def yaml():
    if importlib.util.find_spec("yaml") is None:
        missing("pyyaml")
    import yaml

    return yaml


@pytest.fixture(scope="session")
def compose(yaml) -> dict:
    """docker-compose.yml, parsed."""
    return yaml.safe_load((ROOT / "docker-compose.yml").read_text())
