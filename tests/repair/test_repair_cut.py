"""Cutting regions out: loops, growth of pinched holes, defects inside and outside."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.repair.cut import cut_region, outside_defects
from spacemesh.repair.patch import sub_mesh
from spacemesh.repair.region import (
    DEFECTS_OUTSIDE_REGION,
    WHOLE_MESH_REGION,
    Region,
    RegionError,
)
from spacemesh.topology import count_vertex_fans


def kept_mesh(cut) -> PolygonMesh:
    return sub_mesh(cut.mesh, cut.kept_faces)


def check_loops(cut) -> None:
    """Each hole halfedge i -> next is the twin of a kept boundary side next -> i."""
    kept = kept_mesh(cut)
    sides = {tuple(h) for h in kept.halfedges.tolist()}
    boundary = set(cut.boundary.tolist())
    for loop in cut.loops:
        assert len(loop) >= 3 and len(set(loop.tolist())) == len(loop)
        for a, b in zip(loop, np.roll(loop, -1), strict=True):
            assert (b, a) in sides and (a, b) not in sides
    assert sum(len(loop) for loop in cut.loops) == len(boundary)
    positions = {int(v): i for i, v in enumerate(cut.boundary)}
    for loop in cut.loops:
        for a, b in zip(loop, np.roll(loop, -1), strict=True):
            assert cut.loop_next[positions[int(a)]] == positions[int(b)]
            assert cut.loop_prev[positions[int(b)]] == positions[int(a)]
    fans = count_vertex_fans(kept)
    assert np.all(fans[cut.boundary] == 1)


def test_vertex_star_gives_one_loop():
    mesh = icosphere(2)
    cut = cut_region(mesh, Region.from_vertices([0]))
    assert cut.removed_vertices.tolist() == [0]
    assert len(cut.loops) == 1 and len(cut.boundary) == 5 and cut.n_grown == 0
    check_loops(cut)


def test_band_on_a_torus_gives_two_loops():
    mesh = torus_grid(12, 8)
    band = [f for f, face in enumerate(mesh.faces) if np.all(face // 8 == 3) or
            set((face // 8).tolist()) == {3, 4}]
    cut = cut_region(mesh, Region.from_faces(band))
    assert len(cut.loops) == 2
    check_loops(cut)


def test_pinched_hole_grows_until_single_gaps():
    mesh = icosphere(2)
    around = [f for f, face in enumerate(mesh.faces) if 0 in face.tolist()]
    cut = cut_region(mesh, Region.from_faces([around[0], around[2]]))  # touch only at 0
    assert cut.n_grown > 0 and cut.requested.sum() == 2
    assert len(cut.loops) == 1
    check_loops(cut)


def test_quads_touching_at_a_corner_grow():
    mesh = torus_grid(12, 8)
    # faces (i, j) and (i + 1, j + 1) share one vertex
    faces = mesh.faces
    pick = [f for f, face in enumerate(faces) if set(face.tolist()) >= {8 * 3 + 3}]
    a = pick[0]
    b = next(f for f in pick if len(set(faces[f].tolist()) & set(faces[a].tolist())) == 1)
    cut = cut_region(mesh, Region.from_faces([a, b]))
    assert cut.n_grown > 0
    check_loops(cut)


def octahedron() -> PolygonMesh:
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
             [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return PolygonMesh.from_faces(v, faces)


def test_region_that_grows_to_the_whole_mesh():
    mesh = octahedron()
    # a checkerboard: every vertex keeps two faces that touch only at it
    with pytest.raises(RegionError, match="grows") as caught:
        cut_region(mesh, Region.from_faces([0, 2, 5, 7]))
    assert caught.value.kind == WHOLE_MESH_REGION


def test_two_disjoint_kept_faces_leave_two_loops():
    cut = cut_region(cube_quads(), Region.from_faces([0, 1, 2, 3]))
    assert len(cut.loops) == 2 and len(cut.removed_vertices) == 0
    check_loops(cut)


def open_icosphere() -> tuple[PolygonMesh, list[int]]:
    mesh = icosphere(2)
    faces = mesh.face_indices.reshape(-1, 3)
    hole = np.flatnonzero((faces == 0).any(axis=1))[:2]
    keep = np.ones(len(faces), dtype=bool)
    keep[hole] = False
    return PolygonMesh.from_faces(mesh.vertices, faces[keep]), faces[hole].tolist()


def test_open_mesh_accepted_when_the_region_covers_its_hole():
    mesh, _ = open_icosphere()
    cut = cut_region(mesh, Region.sphere(mesh.vertices[0], 0.35))
    assert len(cut.loops) == 1
    check_loops(cut)


def test_open_mesh_with_its_hole_outside_names_the_defect():
    mesh, hole = open_icosphere()
    far = int(np.argmin(mesh.vertices @ mesh.vertices[0]))
    with pytest.raises(RegionError, match="open boundary edges") as caught:
        cut_region(mesh, Region.from_vertices([far]))
    assert caught.value.kind == DEFECTS_OUTSIDE_REGION
    (defect,) = caught.value.details["defects"]
    assert defect["kind"] == "open-boundary" and defect["count"] == 4
    assert set(defect["vertices"]) == {v for f in hole for v in f}


def with_fin() -> tuple[PolygonMesh, int]:
    """An icosphere with an extra triangle on one edge (a non-manifold edge)."""
    mesh = icosphere(2)
    u, v = mesh.faces[0][:2]
    tip = (mesh.vertices[u] + mesh.vertices[v]) * 0.6
    vertices = np.concatenate([mesh.vertices, tip[None]])
    faces = [*mesh.faces, np.array([u, v, len(mesh.vertices)])]
    return PolygonMesh.from_faces(vertices, faces), int(u)


def test_non_manifold_spot_inside_the_region_is_accepted():
    mesh, u = with_fin()
    cut = cut_region(mesh, Region.sphere(mesh.vertices[u], 0.4))
    check_loops(cut)
    assert outside_defects(mesh, cut.region) == []


def test_non_manifold_spot_outside_the_region_is_reported():
    mesh, u = with_fin()
    far = int(np.argmin(mesh.vertices[:-1] @ mesh.vertices[u]))
    with pytest.raises(RegionError) as caught:
        cut_region(mesh, Region.from_vertices([far]))
    kinds = {d["kind"] for d in caught.value.details["defects"]}
    assert {"non-manifold-edges", "open-boundary"} <= kinds
    assert "non-manifold" in str(caught.value)


def two_spheres_touching() -> PolygonMesh:
    a = icosphere(1)
    top = int(np.argmax(a.vertices[:, 2]))
    b_vertices = a.vertices.copy()
    b_vertices[:, 2] = -b_vertices[:, 2]  # mirror (reverses orientation) ...
    b_faces = [f[::-1] for f in a.faces]  # ... so flip the faces back to outward
    b_vertices = b_vertices + 2 * a.vertices[top]
    n = a.n_vertices
    remap = np.arange(n) + n
    remap[top] = top  # glue b's bottom vertex (the mirror of top) onto a's top
    faces = [*a.faces, *[remap[f] for f in b_faces]]
    mesh = PolygonMesh.from_faces(np.concatenate([a.vertices, b_vertices]), faces)
    mesh, _ = mesh.remove_unreferenced_vertices()
    return mesh


def test_pinched_vertex_outside_is_reported_and_inside_is_cut():
    mesh = two_spheres_touching()
    fans = count_vertex_fans(mesh)
    pinch = int(np.flatnonzero(fans > 1)[0])
    far = int(np.argmin(mesh.vertices[:, 2]))
    with pytest.raises(RegionError) as caught:
        cut_region(mesh, Region.from_vertices([far]))
    (defect,) = caught.value.details["defects"]
    assert defect["kind"] == "pinched-vertices" and defect["vertices"] == [pinch]
    cut = cut_region(mesh, Region.from_vertices([pinch]))
    assert len(cut.loops) == 2 and pinch in cut.removed_vertices
    check_loops(cut)
