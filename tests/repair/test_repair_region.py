"""Region forms, their JSON, and the 422 kinds of empty, whole-mesh and malformed regions."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.errors import SpaceMeshError
from spacemesh.examples import icosphere
from spacemesh.repair.region import (
    EMPTY_REGION,
    ERROR_KINDS,
    INVALID_REGION,
    WHOLE_MESH_REGION,
    Region,
    RegionError,
    parse_region,
    region_faces,
)

MESH = icosphere(2)


def brute_force(mesh, inside_vertex) -> np.ndarray:
    return np.array([any(inside_vertex(mesh.vertices[v]) for v in f) for f in mesh.faces])


def test_every_form_selects_faces_with_a_vertex_inside():
    centre, radius = MESH.vertices[7], 0.45
    sphere = parse_region({"sphere": {"center": centre.tolist(), "radius": radius}})
    expected = brute_force(MESH, lambda p: np.sum((p - centre) ** 2) <= radius**2)
    assert np.array_equal(sphere.face_mask(MESH), expected)

    lo, hi = np.array([0.2, -0.3, -1.0]), np.array([1.0, 0.4, 0.1])
    box = parse_region({"box": {"min": lo.tolist(), "max": hi.tolist()}})
    expected = brute_force(MESH, lambda p: bool(np.all((p >= lo) & (p <= hi))))
    assert np.array_equal(box.face_mask(MESH), expected)

    chosen = {3, 40, 41}
    vertices = parse_region({"vertices": sorted(chosen)})
    expected = np.array([bool(chosen & set(f.tolist())) for f in MESH.faces])
    assert np.array_equal(vertices.face_mask(MESH), expected)

    faces = parse_region({"faces": [5, 9, 9, 100]})
    assert np.flatnonzero(faces.face_mask(MESH)).tolist() == [5, 9, 100]


@pytest.mark.parametrize("data", [
    {"faces": [1, 2]},
    {"vertices": [0]},
    {"sphere": {"center": [0.0, 0.0, 1.0], "radius": 0.5}},
    {"box": {"min": [-1.0, -1.0, 0.5], "max": [1.0, 1.0, 1.0]}},
])
def test_json_round_trip(data):
    region = parse_region(data)
    assert region.to_dict() == data
    assert np.array_equal(parse_region(region.to_dict()).face_mask(MESH), region.face_mask(MESH))
    assert parse_region(region) is region


@pytest.mark.parametrize("data", [
    {},
    {"faces": [1], "vertices": [2]},
    {"triangles": [1]},
    {"faces": [1.5]},
    {"faces": ["a"]},
    {"faces": [True]},
    {"faces": [[1, 2], [3]]},
    {"sphere": {"center": [0, 0], "radius": 1}},
    {"sphere": {"center": [0, 0, 0], "radius": -1}},
    {"sphere": {"center": [0, 0, float("nan")], "radius": 1}},
    {"sphere": {"center": [0, 0, 0]}},
    {"sphere": [0, 0, 0, 1]},
    {"box": {"min": [1, 1, 1], "max": [0, 2, 2]}},
    {"box": {"min": [0, 0, 0]}},
    [1, 2, 3],
])
def test_malformed_regions_are_invalid(data):
    with pytest.raises(RegionError) as caught:
        parse_region(data)
    assert caught.value.kind == INVALID_REGION


def test_out_of_range_indices_are_invalid():
    for data in ({"faces": [MESH.n_faces]}, {"faces": [-1]}, {"vertices": [MESH.n_vertices]}):
        with pytest.raises(RegionError, match="out of range") as caught:
            region_faces(MESH, data)
        assert caught.value.kind == INVALID_REGION


def test_empty_and_whole_mesh_regions_have_their_kinds():
    for data in ({"faces": []}, {"vertices": []}, {"sphere": {"center": [5, 5, 5], "radius": 1}},
                 {"box": {"min": [2, 2, 2], "max": [3, 3, 3]}}):
        with pytest.raises(RegionError) as caught:
            region_faces(MESH, data)
        assert caught.value.kind == EMPTY_REGION
    for data in ({"faces": list(range(MESH.n_faces))}, {"sphere": {"center": [0, 0, 0],
                                                                   "radius": 1.01}}):
        with pytest.raises(RegionError) as caught:
            region_faces(MESH, data)
        assert caught.value.kind == WHOLE_MESH_REGION


def test_region_error_is_a_user_error_with_a_known_kind():
    error = RegionError(EMPTY_REGION, "nothing", {"a": 1})
    assert isinstance(error, SpaceMeshError) and isinstance(error, ValueError)
    assert error.kind in ERROR_KINDS and error.details == {"a": 1}
    with pytest.raises(ValueError):
        RegionError("no-such-kind", "x")
    assert Region.sphere([0, 0, 0], 1).kind == "sphere"
