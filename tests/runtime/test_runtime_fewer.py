"""No output crosses: a mesh whose faces still cross after the seeds, the untangling and
the dense fallback is made again from fewer vertices, then split back up to the count
asked for and fitted (MeshGenerator._from_fewer; docs/GEOMETRY.md, "No crossing")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.geometry.intersections import self_intersection_fraction
from spacemesh.runtime import MeshGenerator
from spacemesh.runtime.network import fewer_vertices, plain_spec
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.spec import ModelSpec
from tests.validity import assert_valid_mesh


def _ellipsoid(count: int, seed: int) -> np.ndarray:
    """(count, 3) points on an ellipsoid of semi-axes 1, 0.8 and 0.5."""
    points = np.random.default_rng(seed).normal(size=(count, 3))
    return points / np.linalg.norm(points, axis=1, keepdims=True) * [1.0, 0.8, 0.5]


@pytest.fixture(scope="module")
def spec(shipped):
    return ModelSpec.from_manifest(shipped.manifest)


def test_the_fewer_count_is_the_models_or_half(spec):
    def fewer(**fields):
        return fewer_vertices(spec, GenerateOptions(**fields).resolve(spec))

    assert spec.vertices == 200
    assert fewer(target_vertices=2000) == 200
    assert fewer(target_vertices=201) == 200
    assert fewer() == 100  # the default count: half of it
    assert fewer(target_vertices=60) == 30
    assert fewer(target_vertices=8) == 4
    assert fewer(target_vertices=7) is None  # a tetrahedron cannot cross
    assert fewer(target_vertices=2000, raw=True) is None
    assert fewer(start="noise") is None


def test_a_mesh_that_still_crosses_is_made_from_fewer_vertices(shipped, spec, monkeypatch):
    """Every mesh of 60 vertices or more is said to cross: the request is made again at
    30 and split back up to 60, and the exact test finds no crossing in it."""
    import spacemesh.runtime.pipeline as pipeline

    generator = MeshGenerator(shipped.backend, plain_spec(spec))
    real = pipeline.crosses
    monkeypatch.setattr(pipeline, "crosses",
                        lambda r: r.mesh.n_vertices >= 60 or real(r))
    stages: list[str] = []
    points = _ellipsoid(2048, seed=5)
    result = generator.generate(points, target_vertices=60,
                                stage=lambda name, done, total: stages.append(name))
    assert "fewer" in stages
    assert result.geometry_stats["fewer_vertices"] == 30
    assert result.geometry_stats["fewer_split"] == 30
    assert result.mesh.n_vertices == 60 and result.options.target_vertices == 60
    assert result.n_sampled_vertices <= 30  # the networks placed the fewer vertices
    assert_valid_mesh(result.mesh)
    assert self_intersection_fraction(result.mesh) == 0.0
    assert result.fit.self_intersections == 0
    assert result.fit.points_to_mesh_mean_rel < 0.02
    # both ran, and the timings say so
    assert stages.count("encoder") >= 2
    monkeypatch.setattr(pipeline, "crosses", real)
    kept = generator.generate(points, target_vertices=60)
    assert "fewer_vertices" not in kept.geometry_stats


def test_below_the_smallest_count_the_hull_is_made(shipped, spec, monkeypatch):
    """With nothing left to try (every decoded mesh said to cross, down to 4 vertices),
    the convex hull of the points is what is left: split up to the count asked for at
    each step of the chain back up, fitted, and found crossing nowhere by the exact
    test."""
    import spacemesh.runtime.pipeline as pipeline

    generator = MeshGenerator(shipped.backend, replace(plain_spec(spec), retry_seeds=1))
    monkeypatch.setattr(pipeline, "crosses",
                        lambda r: "convex_hull" not in r.geometry_stats)
    stages: list[str] = []
    points = _ellipsoid(1024, seed=6)
    result = generator.generate(points, target_vertices=16,
                                stage=lambda name, done, total: stages.append(name))
    assert stages.count("hull") == 1 and "fewer" in stages
    assert result.geometry_stats["convex_hull"] is True
    assert result.geometry_stats["fewer_vertices"] == 8  # 16 -> 8 -> 4 -> the hull
    assert result.mesh.n_vertices == 16
    assert_valid_mesh(result.mesh)
    assert self_intersection_fraction(result.mesh) == 0.0
    assert result.fit.self_intersections == 0
    assert result.fit.points_to_mesh_mean_rel < 0.05  # an ellipsoid's hull, fitted


def test_flat_points_keep_the_crossing_mesh(shipped, spec, monkeypatch):
    """Points on one plane span no hull: the request's own mesh is returned, its fit
    report saying what it is."""
    import spacemesh.runtime.pipeline as pipeline

    generator = MeshGenerator(shipped.backend, replace(plain_spec(spec), retry_seeds=1))
    monkeypatch.setattr(pipeline, "crosses", lambda r: True)
    points = np.random.default_rng(6).normal(size=(1024, 3)) * [1.0, 1.0, 0.0]
    result = generator.generate(points, target_vertices=8, surface="closed")
    assert "convex_hull" not in result.geometry_stats
    assert result.mesh.n_vertices <= 8
    assert_valid_mesh(result.mesh)


def test_the_hull_has_at_most_the_corners_asked_for():
    from spacemesh.geometry.hull import hull_mesh
    from spacemesh.primitives import signed_volume

    points = np.random.default_rng(3).normal(size=(500, 3))
    hull = hull_mesh(points, 12)
    assert hull is not None and hull.n_vertices == 12
    assert_valid_mesh(hull)
    assert signed_volume(hull) > 0  # wound outward
    assert self_intersection_fraction(hull) == 0.0
    whole = hull_mesh(points, 10_000)
    assert whole is not None and whole.n_vertices < 500 and signed_volume(whole) > 0
    assert hull_mesh(points * [1.0, 1.0, 0.0], 12) is None  # flat: no volume
