"""Fixtures of the service tests: a tiny exported model and real servers on loopback.

The model is the run's tiny model (``toy_model`` of tests/conftest.py). Servers run
:class:`SpaceMeshServer` (uvicorn + gRPC) in a background thread (:class:`BackgroundServer`)
on 127.0.0.1 with ports picked by the OS.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

#: Without the service's dependencies (a model-only install) these tests are not collected.
SERVICE_DEPENDENCIES = ("fastapi", "uvicorn", "grpc", "grpc_health", "spacemesh_service")
if not all(importlib.util.find_spec(name) for name in SERVICE_DEPENDENCIES):
    collect_ignore_glob = ["test_*.py"]
else:
    from service_testing import (
        NO_SURFACE_OPTIONS,
        SEEDS_TO_TRY,
        Case,
        make_cloud,
        server_settings,
    )

    from spacemesh_service.server import BackgroundServer


# ---------------------------------------------------------------------- model
@pytest.fixture(scope="session")
def toy_repository(toy_model) -> Path:
    """Version folder of the tiny model (``toy_model``, tests/conftest.py)."""
    return toy_model.repository


@pytest.fixture(scope="session")
def generator(toy_repository):
    from spacemesh.runtime import MeshGenerator

    return MeshGenerator.from_repository(toy_repository, threads=1)


@pytest.fixture(scope="session")
def case(generator) -> Case:
    points = make_cloud()
    good = empty = None
    for seed in range(SEEDS_TO_TRY):
        mesh = generator.generate(points, seed=seed).mesh
        if mesh.n_faces and good is None:
            good = seed
        if not mesh.n_faces and empty is None:
            empty = seed
        if good is not None and empty is not None:
            break
    if good is None:  # a failure, never a skip: ~70 service, client and deploy tests use it
        pytest.fail(f"the tiny test model made no surface from the test cloud for any of "
                    f"{SEEDS_TO_TRY} seeds: the toy model or the pipeline regressed "
                    f"(spacemesh.train.toy.build_toy_model, service_testing.make_cloud)",
                    pytrace=False)
    no_surface = {"seed": empty} if empty is not None else {"seed": 0, **NO_SURFACE_OPTIONS}
    if generator.generate(points, **no_surface).mesh.n_faces:
        pytest.fail(f"the tiny test model made a surface with {no_surface}: the no-surface "
                    "tests need other options (service_testing.NO_SURFACE_OPTIONS)",
                    pytrace=False)
    return Case(points, good, empty, no_surface)


# ---------------------------------------------------------------------- servers
@pytest.fixture(scope="session")
def start_server(toy_repository):
    """``start_server(generator=None, **settings) -> BackgroundServer``; stopped at the end."""
    servers: list[BackgroundServer] = []

    def start(generator=None, wait_ready=True, **changes) -> BackgroundServer:
        server = BackgroundServer(server_settings(toy_repository, **changes), generator)
        servers.append(server.start(wait_ready))
        return server

    yield start
    for server in servers:
        server.stop()


@pytest.fixture(scope="session")
def server(start_server, generator) -> BackgroundServer:
    """The shared server (batches of up to 4, 2 ms delay)."""
    return start_server(generator)


@pytest.fixture(scope="session")
def http(server):
    import httpx

    with httpx.Client(base_url=server.url, timeout=60) as client:
        yield client
