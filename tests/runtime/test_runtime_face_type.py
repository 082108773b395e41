"""``face_type``: the shipped model's triangles, or flat regions merged into planar
polygons (``spacemesh.geometry.polygons``), on the real pipeline."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.examples import cube_quads
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.geometry.polygons import COLLAPSE_SHARE
from spacemesh.primitives import sample_surface
from spacemesh.runtime import MeshGenerator
from spacemesh.runtime.options import OptionError
from spacemesh.runtime.pipeline import POLYGON_PLANARITY
from tests.validity import assert_valid_mesh


@pytest.fixture(scope="module")
def generator():
    return MeshGenerator.from_repository(None, threads=1)


@pytest.fixture(scope="module")
def box_points():
    points, _ = sample_surface(cube_quads(), 2048, np.random.default_rng(0))
    return points * [3.0, 2.0, 1.0] + 10.0  # any frame and scale


def test_polygons_are_planar_fewer_faces_over_the_same_surface(generator, box_points):
    triangles = generator.generate(box_points, seed=0)
    polygons = generator.generate(box_points, seed=0, face_type="polygons")
    assert triangles.options.face_type == "triangles" and triangles.mesh.is_triangle_mesh()
    assert polygons.options.face_type == "polygons"
    assert polygons.mesh.n_faces < 0.3 * triangles.mesh.n_faces  # a box is mostly flat
    assert max(polygons.mesh.face_sizes) > 4
    assert_valid_mesh(polygons.mesh)
    assert 0.0 < polygons.fit.face_planarity <= 0.001 and triangles.fit.face_planarity == 0.0
    assert not self_intersecting_faces(polygons.mesh).any()
    # flat regions lose their interior vertices (the count asked for is the triangles')
    assert polygons.mesh.n_vertices < 0.5 * triangles.mesh.n_vertices
    # the collapses move the surface by about their error at most (a share of the
    # planarity tolerance), the merging not at all
    assert polygons.fit.points_to_mesh_mean_rel <= (
        triangles.fit.points_to_mesh_mean_rel + COLLAPSE_SHARE * POLYGON_PLANARITY)
    assert polygons.fit.mesh_to_points_mean_rel == pytest.approx(
        triangles.fit.mesh_to_points_mean_rel, rel=0.1)


@pytest.mark.parametrize(("options", "text"), [
    ({"face_type": "quads"}, "quad-dominant"),
    ({"face_type": "polygons", "raw": True}, "raw"),
    ({"face_type": "ngons"}, "one of triangles, polygons, quads"),
])
def test_what_the_model_cannot_make_is_refused(generator, box_points, options, text):
    with pytest.raises(OptionError, match=text) as info:
        generator.generate(box_points, **options)
    assert info.value.option == "face_type"
