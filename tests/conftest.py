"""Fixtures of every test folder: the tiny model, trained and exported once per run.

The model is built through the real command line (:func:`spacemesh.train.toy.build_toy_model`)
in the run's temporary folder, or in ``SPACEMESH_TEST_TOY_DIR`` when that is set (to keep it
between runs; ``scripts/test.sh`` sets it and starts the build in the background before
its style, type and layer checks, so that the tests find it built). Under pytest-xdist
(``scripts/test.sh`` runs two workers) the workers share one build, under a file lock:
the controller starts it in a background process as the session starts
(:func:`pytest_sessionstart`; it finds a build already made or under way and waits for
it), and the files that do not need it run first (:func:`pytest_collection_modifyitems`),
so that neither worker sits idle for its 50 s.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

_background: list[subprocess.Popen] = []


def _toy_directory(run_folder: Path) -> Path:
    """Where the tiny model of a run whose temporary folder is ``run_folder`` goes."""
    folder = os.environ.get("SPACEMESH_TEST_TOY_DIR")
    return Path(folder) if folder else run_folder / "spacemesh-toy-model"


def pytest_sessionstart(session: pytest.Session) -> None:
    """The xdist controller (whose temporary folder holds the workers' ``gw0``, ``gw1``)
    starts the tiny model's build in the background; the workers wait on its lock."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    if not all(importlib.util.find_spec(name) for name in ("torch", "onnxscript", "filelock")):
        return
    directory = _toy_directory(config._tmp_path_factory.getbasetemp())  # as xdist's own
    directory.parent.mkdir(parents=True, exist_ok=True)
    log = open(str(directory) + ".log", "w")  # the process writes it
    _background.append(subprocess.Popen(
        [sys.executable, "-m", "spacemesh.train.toy", str(directory)],  # under its lock
        stdout=log, stderr=subprocess.STDOUT))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The files with no test that needs the tiny model run first (each file's tests
    stay together and in order), so that the workers have work while it builds."""
    needs = {item.path for item in items if "toy_model" in getattr(item, "fixturenames", ())}
    items.sort(key=lambda item: item.path in needs)


def pytest_sessionfinish(session: pytest.Session) -> None:
    """A build still running when the session ends (a run stopped early) is stopped."""
    for process in _background:
        if process.poll() is None:
            process.terminate()
        process.wait()


@pytest.fixture(scope="session")
def toy_model(tmp_path_factory):
    """A :class:`spacemesh.train.toy.ToyModel` (tests/export, runtime, evaluate, repair,
    train, and the servers of tests/service, client, browser and deploy)."""
    pytest.importorskip("torch")
    pytest.importorskip("onnxscript")
    from spacemesh.train.toy import build_toy_model_once

    base = tmp_path_factory.getbasetemp()  # a worker's is gw0, gw1, ... of the run's
    directory = _toy_directory(base.parent if "PYTEST_XDIST_WORKER" in os.environ else base)
    return build_toy_model_once(directory)
