"""A repair's new polygons that still cross once its samplings are spent are triangulated
again (spacemesh.repair.crossings.uncross_polygons), and two crossing caps of a tube are
replaced by the band between them (band_triangles)."""

from __future__ import annotations

import numpy as np
from repair_testing import assert_closed_manifold

from spacemesh.examples import icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset, signed_volume
from spacemesh.repair.crossings import band_triangles, new_crossings, uncross_polygons
from spacemesh.repair.fill.loops import patch_loops
from spacemesh.repair.splice import Spliced


def _with_polygons(mesh: PolygonMesh, removed: np.ndarray, extra: PolygonMesh | None = None
                   ) -> tuple[Spliced, PolygonMesh]:
    """``mesh`` with the ``removed`` faces replaced by one polygon per boundary loop (new
    faces last), plus the faces of ``extra`` kept beside it; and the removed faces, as
    the region's surface."""
    loops = patch_loops(mesh, removed)
    faces = [list(f) for f in faces_subset(mesh, ~removed).faces]
    vertices = mesh.vertices
    if extra is not None:
        faces += [[v + mesh.n_vertices for v in f] for f in extra.faces]
        vertices = np.concatenate([vertices, extra.vertices])
    n_kept = len(faces)
    faces += [list(map(int, loop)) for loop in loops]
    out, _ = PolygonMesh.from_faces(vertices, faces).remove_unreferenced_vertices()
    source = np.where(np.arange(out.n_faces) < n_kept, np.arange(out.n_faces), -1)
    surface = faces_subset(mesh, removed)
    return Spliced(out, np.arange(out.n_vertices), source, 0, len(loops)), surface


def test_a_crossing_cap_becomes_a_fan_on_the_surface():
    """A sphere's polar cap closed by one flat polygon that cuts through a small sphere
    inside it: the least-area triangulation is as flat and crosses too, the fan from the
    centroid moved onto the cap's surface does not, so the polygon becomes that fan."""
    sphere = icosphere(2)
    removed = np.array([sphere.vertices[f][:, 2].min() > 0.75 for f in sphere.faces])
    small = icosphere(1)
    inner = PolygonMesh(small.vertices * 0.12 + np.array([0.0, 0.0, 0.78]),
                        small.face_indices, small.face_offsets)
    spliced, surface = _with_polygons(sphere, removed, inner)
    assert len(patch_loops(sphere, removed)) == 1
    assert new_crossings(spliced) == 1  # the cap polygon cuts the small sphere

    mended, count = uncross_polygons(spliced, surface)

    assert count == 1 and new_crossings(mended) == 0
    assert_closed_manifold(mended.mesh)
    assert mended.n_new_vertices == 1  # the fan's centre, on the cap's surface
    centre = mended.mesh.vertices[-1]
    assert abs(np.linalg.norm(centre) - 1.0) < 0.05
    kept = mended.face_source >= 0
    assert np.array_equal(mended.face_source[kept],
                          spliced.face_source[spliced.face_source >= 0])
    assert mended.n_new_faces == int(np.sum(~kept)) == len(patch_loops(sphere, removed)[0])


def test_no_crossing_leaves_the_repair_as_it_is():
    sphere = icosphere(2)
    removed = np.array([sphere.vertices[f][:, 2].min() > 0.75 for f in sphere.faces])
    spliced, surface = _with_polygons(sphere, removed)
    assert new_crossings(spliced) == 0
    mended, count = uncross_polygons(spliced, surface)
    assert count == 0 and mended is spliced


def _torus_ring() -> tuple[PolygonMesh, np.ndarray]:
    """A quad torus (major radius 2, tube radius 1, 24 by 8) and one ring of its 8 quads
    around the tube (faces are made ring by ring)."""
    torus = torus_grid(24, 8)
    return torus, np.arange(torus.n_faces) // 8 == 3


def test_the_band_between_two_caps_restores_the_tube():
    """The ring replaced by the band between its two loops (each in the direction a fill
    uses): the torus is closed, oriented and of genus 1 again, with about its volume."""
    torus, ring = _torus_ring()
    loops = patch_loops(torus, ring)
    assert len(loops) == 2 and all(len(loop) == 8 for loop in loops)

    band = band_triangles(torus.vertices, loops[0], loops[1])

    assert band.shape == (16, 3)
    faces = [list(f) for f in faces_subset(torus, ~ring).faces] + band.tolist()
    mesh = PolygonMesh.from_faces(torus.vertices, faces)
    assert_closed_manifold(mesh)
    assert mesh.n_vertices - len(mesh.edges) + mesh.n_faces == 0  # genus 1
    assert abs(signed_volume(mesh) - signed_volume(torus)) < 0.02 * signed_volume(torus)


def test_two_crossing_caps_are_bridged():
    """The ring closed by one polygon per loop (a cap across the tube at each end), with a
    small sphere inside the tube that both caps cut, and any fan from a loop too: the two
    caps are replaced by the band, which follows the tube's wall and crosses nothing."""
    torus, ring = _torus_ring()
    angle = 3.5 * 2 * np.pi / 24  # the middle of the ring
    small = icosphere(1)
    inner = PolygonMesh(small.vertices * 0.4 + 2 * np.array([np.cos(angle), np.sin(angle), 0]),
                        small.face_indices, small.face_offsets)
    spliced, surface = _with_polygons(torus, ring, inner)
    assert new_crossings(spliced) == 2

    mended, count = uncross_polygons(spliced, surface)

    assert count == 2 and new_crossings(mended) == 0
    assert_closed_manifold(mended.mesh)
    assert mended.n_new_vertices == 0 and mended.n_new_faces == 16
    assert np.all(mended.mesh.face_sizes[mended.face_source < 0] == 3)


def test_a_polygon_folded_over_a_new_triangle_is_merged_with_it():
    """The cap closed by a new triangle from one side of its loop out to a new vertex
    beside the sphere, level with the loop, and a polygon through that vertex over the
    rest. With no surface to lift a fan's centre onto, no triangulation of the polygon
    alone avoids the triangle (its least-area one needs the triangle's side, a fan from
    the level centroid overlaps it), so both are merged and the loop triangulated again,
    and the vertex no face uses any more is dropped."""
    sphere = icosphere(2)
    removed = np.array([sphere.vertices[f][:, 2].min() > 0.75 for f in sphere.faces])
    loop = patch_loops(sphere, removed)[0]
    middle = sphere.vertices[loop[:2]].mean(axis=0)
    spike = middle + 0.5 * np.array([middle[0], middle[1], 0.0])  # outward, level
    kept = [list(f) for f in faces_subset(sphere, ~removed).faces]
    x = sphere.n_vertices
    faces = [*kept, [loop[0], loop[1], x], [loop[0], x, *loop[1:]]]
    mesh = PolygonMesh.from_faces(np.concatenate([sphere.vertices, spike[None]]), faces)
    mesh, _ = mesh.remove_unreferenced_vertices()
    source = np.where(np.arange(mesh.n_faces) < len(kept), np.arange(mesh.n_faces), -1)
    spliced = Spliced(mesh, np.arange(mesh.n_vertices), source, 1, 2)
    assert new_crossings(spliced) == 2

    no_surface = faces_subset(sphere, np.zeros(sphere.n_faces, dtype=bool))
    mended, count = uncross_polygons(spliced, no_surface)

    assert count == 2 and new_crossings(mended) == 0
    assert_closed_manifold(mended.mesh)
    assert mended.n_new_vertices == 0 and mended.n_new_faces == len(loop) - 2
    assert mended.mesh.n_vertices == mesh.n_vertices - 1
    assert np.array_equal(mended.mesh.vertices, mesh.vertices[:-1])


def test_a_repair_whose_samplings_all_cross_is_uncrossed(monkeypatch):
    """Where every sampling's fitted patch is said to cross, the repair keeps the one with
    the fewest crossings and runs the mending on it: its fill reports the faces it
    replaced and its timings the step; the result is still a closed manifold."""
    from repair_testing import NoiseBackend, make_spec

    import spacemesh.repair.api as api
    from spacemesh.repair import repair_mesh

    said: list[int] = []

    def always_crossing(spliced):
        said.append(new_crossings(spliced))
        return 1

    monkeypatch.setattr(api, "new_crossings", always_crossing)
    result = repair_mesh(icosphere(3), {"vertices": [0]}, backend=NoiseBackend(),
                         spec=make_spec(), seed=7)
    assert len(said) == result.stats.samplings == api.TOPOLOGY_ATTEMPTS
    assert result.stats.fill["uncrossed_faces"] >= 0 and "uncross" in result.stats.timings
    assert_closed_manifold(result.mesh)
    assert new_crossings(api.Spliced(result.mesh, result.vertex_map, result.face_source,
                                     result.stats.new_vertices, result.stats.new_faces)) == 0


def test_a_crossing_hole_fill_is_replaced_by_one_that_crosses_nothing():
    """An automatic region's fill (here the flat one over a sphere's polar hole) that
    cuts through a small sphere inside: the faired fan over the same loop, which
    continues the sphere's surface, replaces it (spacemesh.repair.fill.finish.
    uncrossed_fill), and nothing the region made crosses any more."""
    from spacemesh.geometry.intersections import crossing_faces
    from spacemesh.repair.fill import DEFAULT_POLICY, FilledBy
    from spacemesh.repair.fill.finish import uncrossed_fill
    from spacemesh.repair.fill.flat import min_area_triangles
    from spacemesh.repair.fill.passes import Passes

    sphere = icosphere(2)
    removed = np.array([sphere.vertices[f][:, 2].min() > 0.75 for f in sphere.faces])
    loop = patch_loops(sphere, removed)[0]
    small = icosphere(1)
    inner = small.vertices * 0.12 + np.array([0.0, 0.0, 0.78])
    kept = [list(f) for f in faces_subset(sphere, ~removed).faces]
    kept += [[v + sphere.n_vertices for v in f] for f in small.faces]
    flat = loop[min_area_triangles(sphere.vertices[loop])].tolist()
    mesh, _ = PolygonMesh.from_faces(np.concatenate([sphere.vertices, inner]),
                                     kept + flat).remove_unreferenced_vertices()
    state = Passes.of(mesh)
    state.made_by = np.where(np.arange(mesh.n_faces) >= len(kept), 0, -1)
    assert len(crossing_faces(mesh, state.made_by == 0)) > 0

    assert uncrossed_fill(state, 0, DEFAULT_POLICY) == FilledBy.FALLBACK

    assert len(crossing_faces(state.mesh, state.made_by == 0)) == 0
    assert_closed_manifold(state.mesh)
    made = state.mesh.vertices[np.unique(np.concatenate(
        [state.mesh.faces[f] for f in np.flatnonzero(state.made_by == 0)]))]
    assert made[:, 2].max() > 0.95  # the fan follows the sphere up to its pole


def test_a_hole_fill_that_does_not_cross_is_left_alone():
    from spacemesh.repair.fill import DEFAULT_POLICY
    from spacemesh.repair.fill.finish import uncrossed_fill
    from spacemesh.repair.fill.passes import Passes

    sphere = icosphere(2)
    state = Passes.of(sphere)
    state.made_by = np.where(np.arange(sphere.n_faces) < 5, 0, -1)
    mesh_before = state.mesh
    assert uncrossed_fill(state, 0, DEFAULT_POLICY) is None and state.mesh is mesh_before
