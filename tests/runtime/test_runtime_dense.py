"""A dense decode simplified to the count asked for (GeometryOptions.dense_factor; the
shipped model's is 2): here the shipped model decodes four times the vertices, the
geometry stage fits them and collapses them back (spacemesh.geometry.simplify)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.runtime import MeshGenerator
from spacemesh.runtime.network import decode_count, plain_spec
from spacemesh.runtime.options import GenerateOptions
from tests.validity import assert_valid_mesh


def test_a_dense_decode_is_simplified_to_the_target(shipped):
    from spacemesh.runtime.spec import ModelSpec

    spec = ModelSpec.from_manifest(shipped.manifest)
    assert spec.geometry.dense_factor == 2.0  # the shipped default
    dense_spec = replace(spec, geometry=replace(spec.geometry, dense_factor=4.0))
    generator = MeshGenerator(shipped.backend, dense_spec)
    options = GenerateOptions(target_vertices=60).resolve(dense_spec)
    assert decode_count(dense_spec, options) == 240
    assert decode_count(dense_spec, replace(options, raw=True)) == 60
    assert decode_count(plain_spec(spec), options) == 60
    assert decode_count(spec, options) == 120  # the shipped model's own factor
    # at most MAX_DENSE_VERTICES, and never fewer than asked for
    assert decode_count(dense_spec, replace(options, target_vertices=300)) == 1024
    assert decode_count(dense_spec, replace(options, target_vertices=2000)) == 2000
    rng = np.random.default_rng(4)
    d = rng.normal(size=(2048, 3))
    points = d / np.linalg.norm(d, axis=1, keepdims=True) * [1.0, 0.7, 0.4]
    result = generator.generate(points, target_vertices=60)
    assert_valid_mesh(result.mesh)
    # the dense decode has no handle, so it was kept (the plain one was not decoded)
    assert result.decode_stats["dense_genus"] == [0, None]
    collapsed = result.geometry_stats["simplify"]["collapsed"]
    assert collapsed > 100 and result.mesh.n_vertices == 60
    assert result.fit.self_intersections == 0
    assert result.fit.points_to_mesh_mean_rel < 0.01


def test_a_dense_mesh_that_still_crosses_gives_way_to_the_plain_decode(shipped, monkeypatch):
    """No output may cross: when the chosen dense mesh's faces still cross after the
    untangling, the request runs again at the count asked for, and that mesh is kept
    when it does not cross (here every simplified mesh is said to cross)."""
    import spacemesh.runtime.pipeline as pipeline
    from spacemesh.runtime.spec import ModelSpec

    spec = ModelSpec.from_manifest(shipped.manifest)
    dense_spec = replace(spec, geometry=replace(spec.geometry, dense_factor=2.0))
    generator = MeshGenerator(shipped.backend, dense_spec)
    real = pipeline.crosses
    monkeypatch.setattr(pipeline, "crosses",
                        lambda r: "simplify" in r.geometry_stats or real(r))
    stages: list[str] = []
    points = np.random.default_rng(5).normal(size=(2048, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    result = generator.generate(points, target_vertices=60,
                                stage=lambda name, done, total: stages.append(name))
    assert "simplify" not in result.geometry_stats  # the plain decode's mesh
    assert "dense_genus" not in result.decode_stats
    assert_valid_mesh(result.mesh)
    assert result.mesh.n_vertices == 60
    # both ran, and the timings say so: the dense seeds and their retries, then the plain
    assert stages.count("encoder") >= 2
    assert result.timings["geometry"] > 0
    monkeypatch.setattr(pipeline, "crosses", real)
    kept = generator.generate(points, target_vertices=60)
    assert "simplify" in kept.geometry_stats  # without the crossing, the dense mesh stays


def test_below_the_models_count_a_dense_decode_keeps_its_handles(shipped):
    """The topology guard (a dense decode gives way to the plain one when that has
    fewer handles) applies from the model's own count up; below it the plain decode is
    too coarse to hold handles, so the dense one is kept without decoding the other.
    A torus, whose dense decode has its handle, at both sides of the model's count."""
    from spacemesh.examples import torus_grid
    from spacemesh.primitives import sample_surface
    from spacemesh.runtime.spec import ModelSpec
    from spacemesh.topology import surface_topology

    spec = ModelSpec.from_manifest(shipped.manifest)
    generator = MeshGenerator(shipped.backend, spec)
    points, _ = sample_surface(torus_grid(32, 16), 2048, np.random.default_rng(3))
    small = generator.generate(points, target_vertices=spec.vertices // 2)
    assert small.decode_stats["dense_genus"] == [1, None]  # the plain one not decoded
    assert surface_topology(small.mesh).genus == 1
    assert_valid_mesh(small.mesh)
    default = generator.generate(points)
    dense_genus, plain_genus = default.decode_stats["dense_genus"]
    assert dense_genus == 1 and plain_genus is not None  # the guard ran
