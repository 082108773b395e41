"""A dense decode simplified to the count asked for (GeometryOptions.dense_factor, off by
default): the shipped model decodes four times the vertices, and the geometry stage
collapses them back (spacemesh.geometry.simplify)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.runtime import MeshGenerator
from spacemesh.runtime.network import decode_count
from spacemesh.runtime.options import GenerateOptions
from tests.validity import assert_valid_mesh


def test_a_dense_decode_is_simplified_to_the_target(shipped):
    from spacemesh.runtime.spec import ModelSpec

    spec = ModelSpec.from_manifest(shipped.manifest)
    assert spec.geometry.dense_factor == 1.0  # off by default
    dense_spec = replace(spec, geometry=replace(spec.geometry, dense_factor=4.0))
    generator = MeshGenerator(shipped.backend, dense_spec)
    options = GenerateOptions(target_vertices=60).resolve(dense_spec)
    assert decode_count(dense_spec, options) == 240
    assert decode_count(dense_spec, replace(options, raw=True)) == 60
    assert decode_count(spec, options) == 60
    rng = np.random.default_rng(4)
    d = rng.normal(size=(2048, 3))
    points = d / np.linalg.norm(d, axis=1, keepdims=True) * [1.0, 0.7, 0.4]
    result = generator.generate(points, target_vertices=60)
    assert_valid_mesh(result.mesh)
    dense_genus, plain_genus = result.decode_stats["dense_genus"]  # both decodes' genus
    assert dense_genus <= plain_genus == 0  # so the dense decode was kept, and simplified
    collapsed = result.geometry_stats["simplify"]["collapsed"]
    assert collapsed > 100 and result.mesh.n_vertices == 60
    assert result.fit.self_intersections == 0
    assert result.fit.points_to_mesh_mean_rel < 0.01
