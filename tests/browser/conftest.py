"""Fixtures of the browser tests: the real server of tests/service and a headless Chromium.

The tiny exported model and the server fixtures are those of ``tests/service/conftest.py``,
imported rather than copied (as tests/client does). The browser is Debian's ``chromium``
driven through ``/usr/bin/chromedriver`` (:mod:`tests.browser.browser_testing`); without
them (or selenium) the tests are skipped, saying why.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SERVICE_TESTS = Path(__file__).resolve().parents[1] / "service"
DEPENDENCIES = ("httpx", "fastapi", "uvicorn", "grpc", "grpc_health", "spacemesh_service")
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
def browser(tmp_path_factory):
    """A headless Chromium (selenium), downloads going to ``browser.download_dir``."""
    from tests.browser.browser_testing import missing_browser, start_chromium

    reason = missing_browser()
    if reason:
        pytest.skip(reason)
    driver = start_chromium(tmp_path_factory.mktemp("chromium"))
    yield driver
    driver.quit()
