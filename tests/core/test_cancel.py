"""Cooperative cancellation (spacemesh.cancel): checkpoints do nothing outside a scope,
raise inside one whose check says the work is abandoned, and sit inside the long loops of
the geometry stage, the collapses and the decode."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.cancel import Cancelled, cancel_scope, cancelled, checkpoint
from spacemesh.examples import icosphere
from spacemesh.primitives import sample_surface


def after(calls: int):
    """A check that turns True on its ``calls``-th call, counting its calls."""
    count = {"n": 0}

    def check() -> bool:
        count["n"] += 1
        return count["n"] >= calls

    return check, count


def test_checkpoints_raise_only_inside_a_scope_that_says_so():
    checkpoint()  # no scope: nothing happens
    assert not cancelled()
    with cancel_scope(lambda: False):
        checkpoint()
        assert not cancelled()
        with cancel_scope(lambda: True), pytest.raises(Cancelled):
            assert cancelled()
            checkpoint()
        checkpoint()  # the outer scope is back
    checkpoint()


@pytest.mark.parametrize("where", ["geometry", "simplify", "untangle"])
def test_long_stages_stop_inside_their_loops(where):
    from spacemesh.geometry import refine_geometry
    from spacemesh.geometry.simplify import simplify
    from spacemesh.geometry.untangle import untangle

    mesh = icosphere(3)
    points, _ = sample_surface(mesh, 2000, np.random.default_rng(0))
    if where == "untangle":  # a folded mesh: one vertex pushed through the sphere
        moved = mesh.vertices.copy()
        moved[0] = -1.3 * moved[0]
        mesh = mesh.with_vertices(moved)
    run = {"geometry": lambda: refine_geometry(mesh, points),
           "simplify": lambda: simplify(mesh, points, target_vertices=40),
           "untangle": lambda: untangle(mesh)}[where]
    check, count = after(1)
    with cancel_scope(check), pytest.raises(Cancelled):
        run()
    assert count["n"] == 1  # stopped at its first checkpoint, inside the stage
    run()  # without a scope the same work runs to its end


def test_the_decode_stops_inside_its_rounds(shipped_generator_points):
    generator, points = shipped_generator_points
    check, count = after(1)
    with cancel_scope(check), pytest.raises(Cancelled):
        generator.generate(points, raw=True)
    assert count["n"] == 1


@pytest.fixture(scope="module")
def shipped_generator_points():
    pytest.importorskip("onnxruntime")
    from spacemesh.runtime import MeshGenerator
    from spacemesh.runtime.repository import default_model_dir

    if not default_model_dir().exists():
        pytest.skip("no shipped model in this checkout")
    d = np.random.default_rng(2).normal(size=(2048, 3))
    return MeshGenerator.from_repository(threads=1), d / np.linalg.norm(d, axis=1,
                                                                      keepdims=True)
