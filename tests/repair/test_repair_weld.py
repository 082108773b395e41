"""Welding vertices split at seams (``weld=True``): the map, the region, the hint, a repair."""

from __future__ import annotations

import numpy as np
import pytest
from repair_testing import (
    NoiseBackend,
    assert_closed_manifold,
    flat_shaded,
    geometric_faces,
    make_spec,
)

from spacemesh.examples import icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.repair import Region, RegionError, plan_repair, repair_mesh, weld_vertices
from spacemesh.repair.cut import cut_region
from spacemesh.repair.region import DEFECTS_OUTSIDE_REGION, INVALID_REGION
from spacemesh.repair.weld import coincident_vertices, weld_region
from spacemesh.topology import check_topology


# ---------------------------------------------------------------------- weld_vertices
def test_weld_keeps_first_occurrence_order_and_maps_every_vertex():
    vertices = np.array([[1, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [0, 0, 1.0]])
    mesh = PolygonMesh.from_faces(vertices, [[0, 1, 3], [2, 5, 4]])
    welded, vertex_map = weld_vertices(mesh)
    assert vertex_map.tolist() == [0, 1, 0, 2, 1, 3]
    assert welded.vertices.tolist() == [[1, 0, 0], [0, 0, 0], [0, 1, 0], [0, 0, 1]]
    assert np.array_equal(welded.vertices[vertex_map], mesh.vertices)
    assert [f.tolist() for f in welded.faces] == [[0, 1, 2], [0, 3, 1]]
    assert np.array_equal(welded.face_offsets, mesh.face_offsets)
    assert coincident_vertices(mesh) == 2 and coincident_vertices(welded) == 0


def test_weld_merges_exact_positions_only():
    eps = np.nextafter(1.0, 2.0)
    vertices = np.array([[0.0, 0, 0], [-0.0, 0, -0.0], [1, 0, 0], [eps, 0, 0], [0, 1, 0]])
    mesh = PolygonMesh.from_faces(vertices, [[0, 2, 4], [1, 4, 3]])
    welded, vertex_map = weld_vertices(mesh)
    assert vertex_map.tolist() == [0, 0, 1, 2, 3]  # -0.0 is 0.0; 1 + ulp is not 1
    assert welded.n_vertices == 4


def test_a_mesh_without_coincident_vertices_is_unchanged():
    mesh = torus_grid(12, 8)
    welded, vertex_map = weld_vertices(mesh)
    assert np.array_equal(vertex_map, np.arange(mesh.n_vertices))
    assert np.array_equal(welded.vertices, mesh.vertices)
    assert np.array_equal(welded.face_indices, mesh.face_indices)
    assert coincident_vertices(mesh) == 0


def test_flat_shaded_mesh_welds_back_to_the_closed_mesh():
    mesh = icosphere(2)
    split = flat_shaded(mesh)
    assert check_topology(split).n_boundary_edges == 3 * mesh.n_faces
    welded, vertex_map = weld_vertices(split)
    assert welded.n_vertices == mesh.n_vertices
    assert coincident_vertices(split) == split.n_vertices - mesh.n_vertices
    assert check_topology(welded).is_closed_oriented_manifold
    assert geometric_faces(welded) == geometric_faces(mesh)
    assert np.array_equal(welded.vertices[vertex_map], split.vertices)


def test_faces_that_become_degenerate_are_kept_and_reported():
    mesh = flat_shaded(icosphere(1))
    a, b = mesh.faces[0][:2]
    copy = mesh.n_vertices  # a second copy of vertex a, in a face with a and b
    sliver = PolygonMesh.from_faces(np.vstack([mesh.vertices, mesh.vertices[a]]),
                                    [*mesh.faces, [a, b, copy]])
    welded, vertex_map = weld_vertices(sliver)
    assert welded.n_faces == sliver.n_faces  # nothing dropped
    last = welded.faces[-1]
    assert len(set(last.tolist())) == 2 and last[0] == last[2] == vertex_map[a]
    far = int(np.argmin(sliver.vertices @ sliver.vertices[a]))
    with pytest.raises(RegionError) as caught:
        plan_repair(sliver, {"vertices": [far]}, 64, weld=True)
    kinds = {d["kind"]: d for d in caught.value.details["defects"]}
    assert kinds["degenerate-faces"]["faces"] == [sliver.n_faces - 1]


# ---------------------------------------------------------------------- regions
def test_vertex_regions_are_mapped_and_other_forms_kept():
    mesh = icosphere(1)
    split = flat_shaded(mesh)
    welded, vertex_map = weld_vertices(split)
    copies = np.flatnonzero(vertex_map == vertex_map[7])
    around = np.flatnonzero(np.isin(split.face_indices.reshape(-1, 3), copies).any(axis=1))
    assert len(copies) == len(around) >= 5  # one copy per face around the position
    for copy in copies:  # any copy selects every face around the position
        mapped = weld_region({"vertices": [int(copy)]}, vertex_map)
        assert mapped.kind == "vertices" and mapped.indices.tolist() == [vertex_map[7]]
        assert np.array_equal(np.flatnonzero(mapped.face_mask(welded)), around)
    faces = weld_region({"faces": [1, 2]}, vertex_map)
    assert faces.kind == "faces" and faces.indices.tolist() == [1, 2]
    ball = Region.sphere([0, 0, 1], 0.3)
    assert weld_region(ball, vertex_map) is ball
    mask = np.zeros(split.n_faces, dtype=bool)
    assert weld_region(mask, vertex_map) is mask


def test_vertex_indices_are_checked_against_the_original_mesh():
    split = flat_shaded(icosphere(1))
    _, vertex_map = weld_vertices(split)
    assert weld_region({"vertices": [split.n_vertices - 1]}, vertex_map).indices.size == 1
    with pytest.raises(RegionError, match=f"the mesh has {split.n_vertices} vertices") as caught:
        weld_region({"vertices": [split.n_vertices]}, vertex_map)
    assert caught.value.kind == INVALID_REGION
    with pytest.raises(RegionError):
        weld_region({"vertices": [-1]}, vertex_map)


# ---------------------------------------------------------------------- the hint
def test_defects_error_names_the_coincident_vertices_and_weld():
    split = flat_shaded(icosphere(1))
    expected = split.n_vertices - icosphere(1).n_vertices
    with pytest.raises(RegionError) as caught:
        cut_region(split, Region.sphere(split.vertices[0], 0.3))
    error = caught.value
    assert error.kind == DEFECTS_OUTSIDE_REGION
    assert error.details["coincident_vertices"] == expected
    assert f"{expected} vertices share their exact position" in str(error)
    assert "weld=true" in str(error)


def test_no_hint_without_coincident_vertices():
    mesh = icosphere(2)
    faces = mesh.face_indices.reshape(-1, 3)
    opened = PolygonMesh.from_faces(mesh.vertices, faces[1:])  # one hole at face 0
    far = int(np.argmin(mesh.vertices @ mesh.vertices[faces[0, 0]]))
    with pytest.raises(RegionError) as caught:
        cut_region(opened, Region.from_vertices([far]))
    assert caught.value.details["coincident_vertices"] == 0
    assert "weld" not in str(caught.value)


# ---------------------------------------------------------------------- repair
def test_repair_with_weld_closes_a_flat_shaded_mesh():
    mesh = icosphere(2)
    split = flat_shaded(mesh)
    region = {"sphere": {"center": [0.0, 0.0, 1.0], "radius": 0.5}}
    spec = make_spec()
    with pytest.raises(RegionError) as caught:
        repair_mesh(split, region, backend=NoiseBackend(), spec=spec)
    assert caught.value.kind == DEFECTS_OUTSIDE_REGION
    result = repair_mesh(split, region, backend=NoiseBackend(), spec=spec, weld=True)
    assert_closed_manifold(result.mesh)
    assert result.stats.welded_vertices == split.n_vertices - mesh.n_vertices
    assert result.stats.to_dict()["welded_vertices"] == result.stats.welded_vertices
    kept = result.vertex_map >= 0  # every copy maps to the output vertex at its position
    assert np.array_equal(result.mesh.vertices[result.vertex_map[kept]], split.vertices[kept])
    outside = PolygonMesh.from_faces(split.vertices, [f for f, inside in zip(
        split.faces, result.region, strict=True) if not inside])
    assert geometric_faces(outside) <= geometric_faces(result.mesh)
    plain = repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec)
    assert plain.stats.welded_vertices == 0


def test_a_plan_must_match_the_weld_option():
    split = flat_shaded(icosphere(2))
    region = Region.sphere([0, 0, 1], 0.5)
    spec = make_spec()
    plan = plan_repair(split, region, spec.max_vertices, weld=True)
    assert plan.input_mesh is split and plan.cut.mesh is not split
    assert plan.welded_vertices == split.n_vertices - plan.cut.mesh.n_vertices
    with pytest.raises(ValueError, match="weld=True"):
        repair_mesh(split, region, backend=NoiseBackend(), spec=spec, plan=plan)
    result = repair_mesh(split, region, backend=NoiseBackend(), spec=spec, plan=plan,
                         weld=True)
    assert_closed_manifold(result.mesh)
