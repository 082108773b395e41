"""Choosing a hole's fill by probe holes punched nearby (:mod:`spacemesh.repair.fill.probe`)."""

from __future__ import annotations

import numpy as np
import pytest
from auto_meshes import punched

from spacemesh.examples import icosphere
from spacemesh.primitives import faces_subset, triangulate_faces, vertices_of
from spacemesh.repair.cut import defect_vertices
from spacemesh.repair.fill.fairing import fair_patch
from spacemesh.repair.fill.flat import flat_surface
from spacemesh.repair.fill.loops import patch_loops
from spacemesh.repair.fill.policy import DEFAULT_POLICY, FillPolicy
from spacemesh.repair.fill.probe import (
    PROBES,
    choose_fill,
    fill_error,
    preferred_fill,
    probe_errors,
    probe_regions,
    surface_distance,
)
from spacemesh.repair.pinched import hole_loops


def _holed_sphere():
    mesh = punched(icosphere(4), [[0.0, 0.6, 0.8]], radius=0.3)
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    return mesh, loops


def _holes_filled(mesh, policy=DEFAULT_POLICY):
    """``mesh`` repaired with ``{"auto": "holes"}`` by the noise stand-in model under the
    fill ``policy``, checked (``verify_repair`` clean, closed and manifold): its
    RepairResult."""
    from repair_testing import NoiseBackend, assert_closed_manifold, make_spec

    from spacemesh.repair import plan_repair, repair_mesh, verify_repair

    spec = make_spec()
    plan = plan_repair(mesh, {"auto": "holes"}, spec.max_vertices)
    result = repair_mesh(mesh, {"auto": "holes"}, backend=NoiseBackend(), spec=spec, plan=plan,
                         policy=policy)
    assert verify_repair(plan, result) == []
    assert_closed_manifold(result.mesh)
    return result


def _new_vertices(result):
    """The positions of the vertices a repair added (no input vertex maps to them)."""
    kept = np.zeros(result.mesh.n_vertices, dtype=bool)
    kept[result.vertex_map[result.vertex_map >= 0]] = True
    return result.mesh.vertices[~kept]


def test_fill_error_is_zero_on_the_same_surface_and_grows_as_the_square_of_an_offset():
    sphere = icosphere(2)
    corners = sphere.vertices[triangulate_faces(sphere)[0]]
    assert fill_error(corners, corners) == pytest.approx(0.0, abs=1e-20)
    assert fill_error(corners, corners * 1.1) > fill_error(corners, corners * 1.05) > 0
    square = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]],
                      dtype=float)
    for h in (0.01, 0.02):
        lifted = square + np.array([0.0, 0.0, h])
        assert fill_error(square, lifted) == pytest.approx(2 * h * h, rel=1e-9)
    assert fill_error(square, square[:0]) == np.inf
    # a point over a triangle's side is measured to the side, not to a corner
    d = surface_distance(np.array([[0.5, -0.1, 0.0]]), square[:1])
    assert d[0] == pytest.approx(0.1)


def test_probe_holes_are_discs_of_known_faces_clear_of_the_hole():
    mesh, loops = _holed_sphere()
    known = np.ones(mesh.n_faces, dtype=bool)
    regions = probe_regions(mesh, loops, known)
    assert len(regions) == PROBES
    ring = np.concatenate(loops)
    for faces in regions:
        assert faces.any() and not vertices_of(mesh, faces)[ring].any()
        assert len(patch_loops(mesh, faces)) == 1
    assert not any((a & b).all() for i, a in enumerate(regions) for b in regions[i + 1:])
    # faces that are not the input's (an earlier fill) are never probed
    unknown = np.zeros(mesh.n_faces, dtype=bool)
    for faces in regions:
        unknown |= faces
    others = probe_regions(mesh, loops, ~unknown)
    assert all(not (faces & unknown).any() for faces in others)
    assert probe_regions(mesh, loops, np.zeros(mesh.n_faces, dtype=bool)) == []
    assert preferred_fill(mesh, loops, np.zeros(mesh.n_faces, dtype=bool)) == "fair"


def test_probes_keep_the_fairing_on_a_sphere():
    pytest.importorskip("pymeshfix")
    mesh, loops = _holed_sphere()
    known = np.ones(mesh.n_faces, dtype=bool)
    errors = probe_errors(mesh, loops, known)
    fair, meshfix, used = errors["meshfix"]
    assert used == PROBES
    assert 0 < fair < meshfix  # the thin plate continues a sphere; MeshFix's fill is flatter
    fair_flat, flat, used_flat = errors["flat"]
    assert used_flat == PROBES and fair_flat == pytest.approx(fair) and fair < flat
    report: dict = {}
    assert preferred_fill(mesh, loops, known, report=report) == "fair"
    assert report["probes"] == PROBES and report["probe_fair"] == pytest.approx(fair)
    assert report["probe_flat"] == pytest.approx(flat)


@pytest.mark.parametrize("errors, preferred", [
    # (fairing's, alternative's summed probe error, probes) per alternative
    ({"meshfix": (1.0, 0.9, 4), "flat": (1.0, 0.85, 4)}, "fair"),  # cannot tell apart
    ({"meshfix": (1.0, 0.7, 4), "flat": (1.0, 0.9, 4)}, "meshfix"),  # MeshFix's closer
    ({"meshfix": (1.0, 0.7, 4), "flat": (1.0, 0.5, 4)}, "flat"),  # closer by more
    ({"meshfix": (1.0, 0.7, 0), "flat": (0.0, 0.0, 0)}, "fair"),  # no probe
])
def test_an_alternative_is_taken_where_the_probes_favour_it_by_its_margin(errors, preferred):
    policy = FillPolicy()
    assert policy.meshfix_margin == 0.8 and policy.probe_margin == 0.8
    report: dict = {}
    assert choose_fill(errors, policy, report) == preferred
    assert report["probe_holes"] == max(used for _, _, used in errors.values())


@pytest.mark.parametrize("probing", [True, False])
def test_an_automatic_region_takes_meshfix_fill_where_the_probes_prefer_it(probing):
    pytest.importorskip("pymeshfix")
    # any probe error of MeshFix below 1e9 times the fairing's prefers MeshFix's fill
    policy = FillPolicy(meshfix_margin=1e9, alternatives=("meshfix",), probe_fills=probing)
    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0]], radius=0.4)
    result = _holes_filled(mesh, policy)
    taken = [f["filled_by"] for f in result.stats.findings]
    assert (taken == ["meshfix"]) is probing


def test_no_probe_covers_a_small_part_and_its_fills_do_not_fail():
    pytest.importorskip("pymeshfix")
    from spacemesh.mesh import PolygonMesh

    mesh, loops = _holed_sphere()
    ring = np.concatenate(loops)
    small = icosphere(1)  # an 80-face part beyond the hole
    offset = mesh.vertices[ring].mean(axis=0) * 1.9
    both = PolygonMesh.from_faces(
        np.concatenate([mesh.vertices, 0.2 * small.vertices + offset]),
        [*mesh.faces, *(np.asarray(f) + mesh.n_vertices for f in small.faces)])
    part = np.arange(both.n_faces) >= mesh.n_faces
    # only the small part is known: a probe there would be nearly all of it
    assert probe_regions(both, loops, part) == []
    assert probe_errors(both, loops, part) == {"meshfix": (0.0, 0.0, 0), "flat": (0.0, 0.0, 0)}
    known = np.ones(both.n_faces, dtype=bool)
    regions = probe_regions(both, loops, known)
    assert regions and not any((faces & part).any() for faces in regions)
    for fair, other, used in probe_errors(both, loops, known).values():
        assert used == len(regions) and np.isfinite(fair) and np.isfinite(other)


def test_a_region_patch_falls_into_one_part_per_hole():
    from spacemesh.repair.fill.loops import patch_parts

    sphere = icosphere(2)
    top = sphere.vertices[np.asarray(sphere.faces)].mean(axis=1)[:, 2]  # (F,)
    patch = (top > 0.9) | (top < -0.9)  # two caps, far apart
    parts = patch_parts(sphere, patch)
    assert len(parts) == 2
    assert not (parts[0] & parts[1]).any() and ((parts[0] | parts[1]) == patch).all()
    assert patch_parts(sphere, np.zeros(sphere.n_faces, dtype=bool)) == []
    assert len(patch_parts(sphere, top > -2)) == 1  # a closed mesh is one part


def test_a_patch_the_guard_held_back_is_replaced_by_the_faired_fan():
    calls = []

    def held_back_once(*args, **kwargs):
        out = fair_patch(*args, **kwargs)
        calls.append(kwargs.get("report"))
        if len(calls) == 1 and kwargs.get("report") is not None:
            kwargs["report"]["weight"] = 0.5  # as if the model's patch folded
        return out

    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0]], radius=0.4)
    result = _holes_filled(mesh, FillPolicy(probe_fills=False, fair_patch=held_back_once))
    assert len(calls) == 2  # the model's patch, then the fan
    assert [f["filled_by"] for f in result.stats.findings] == ["fallback"]
    assert result.stats.fallback == "fan"
    new = _new_vertices(result)
    assert len(new) >= 5 and np.abs(np.linalg.norm(new, axis=1) - 1).max() < 0.04


def _held_back(*args, **kwargs):
    """The fairing, reporting that a self-intersection held every patch back."""
    out = fair_patch(*args, **kwargs)
    if kwargs.get("report") is not None:
        kwargs["report"]["weight"] = 0.5
    return out


@pytest.mark.parametrize("unchecked", [True, False])
def test_a_held_back_patch_with_no_probe_takes_meshfix_fill(unchecked):
    pytest.importorskip("pymeshfix")

    policy = FillPolicy(unchecked_fills=unchecked, fair_patch=_held_back)
    mesh = punched(icosphere(2), [[0.0, 0.0, 1.0]], radius=0.6)
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    assert probe_regions(mesh, loops, np.ones(mesh.n_faces, dtype=bool)) == []
    result = _holes_filled(mesh, policy)
    taken = [f["filled_by"] for f in result.stats.findings]
    assert (taken == ["meshfix"]) is unchecked


def test_a_held_back_patch_with_no_probe_takes_the_flat_fill_without_meshfix():
    policy = FillPolicy(fair_patch=_held_back, meshfix_fill=lambda *a, **k: None)
    mesh = punched(icosphere(2), [[0.0, 0.0, 1.0]], radius=0.6)
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    result = _holes_filled(mesh, policy)
    flat = mesh.vertices[flat_surface(mesh.vertices, loops)]
    new = _new_vertices(result)  # the model's patch, laid onto the flat fill
    assert len(new) > 0 and surface_distance(new, flat).max() < 1e-9


def _state_with_cap(offset):
    """A Passes state over an icosphere whose top cap is region 0's patch, with its own
    vertices moved by ``offset`` ((V, 3) -> (V, 3) function of the positions)."""
    from spacemesh.repair.fill.passes import Passes

    sphere = icosphere(3)
    centre_z = sphere.vertices[np.asarray(sphere.faces)].mean(axis=1)[:, 2]  # (F,)
    patch = centre_z > 0.75
    own = vertices_of(sphere, patch) & ~vertices_of(sphere, ~patch)
    p = sphere.vertices.copy()
    p[own] = offset(p[own])
    mesh = sphere.with_vertices(p)
    n_v, n_f = mesh.n_vertices, mesh.n_faces
    state = Passes(mesh, np.arange(n_v), np.where(patch, -1, np.arange(n_f)),
                    np.full(n_f, -1), np.where(own, 0, -1), np.where(patch, 0, -1))
    return state, own


def _spike(x):
    x = x.copy()
    x[np.argmax(x[:, 2])] *= 1.3  # the cap's top vertex pulled out
    return x * 0.97  # and the cap sunk a little


def _laid_cap(fit: bool):
    """The spiked cap laid onto its faired fan (with or without the least-squares fit):
    the state before and after, the cap's own vertices, and the fan's triangles."""
    from spacemesh.repair.fill.fan import faired_fan
    from spacemesh.repair.fill.finish import onto_fan

    policy = FillPolicy(fit_laid=fit)
    state, own = _state_with_cap(_spike)
    before = state.mesh
    fan, _, made = faired_fan(before, state.made_by == 0, policy)
    assert onto_fan(state, 0, policy) == "projected"
    triangles, source = triangulate_faces(fan)
    return before, state.mesh, own, fan.vertices[triangles[made[source]]]


def test_a_spiked_patch_is_laid_onto_the_faired_fan_keeping_its_tessellation():
    before, after, own, fan_corners = _laid_cap(fit=False)
    error_before = np.abs(np.linalg.norm(before.vertices[own], axis=1) - 1).max()
    assert error_before > 0.25
    assert np.array_equal(after.face_indices, before.face_indices)  # same tessellation
    assert np.array_equal(after.vertices[~own], before.vertices[~own])  # ring kept
    assert surface_distance(after.vertices[own], fan_corners).max() < 1e-9  # on the fan
    error_after = np.abs(np.linalg.norm(after.vertices[own], axis=1) - 1).max()
    assert error_after < 0.25 * error_before


def test_a_laid_patch_fitted_to_the_fan_lies_closer_to_it_than_one_interpolating_it():
    _, laid, own, fan_corners = _laid_cap(fit=False)
    before, fitted, _, _ = _laid_cap(fit=True)
    assert np.array_equal(fitted.face_indices, before.face_indices)  # same tessellation
    assert np.array_equal(fitted.vertices[~own], before.vertices[~own])  # ring kept
    patch = np.zeros(before.n_faces, dtype=bool)
    patch[np.unique(before.face_of_corner[own[before.face_indices]])] = True

    def corners(mesh):
        triangles, _ = triangulate_faces(faces_subset(mesh, patch))
        return mesh.vertices[triangles]

    # moved off the fan's surface by about a chord's sag, and no farther from it as a
    # surface (tests/core/test_surface_fit.py measures the fit on a coarse sphere)
    off = surface_distance(fitted.vertices[own], fan_corners)
    assert 1e-6 < off.max() < 0.02
    assert fill_error(fan_corners, corners(fitted)) <= fill_error(fan_corners, corners(laid))


def _dragged(x):
    x = x.copy()
    top = np.argmax(x[:, 2])
    side = np.argmin(x[:, 0])  # the top vertex dragged past a side vertex
    x[top] = x[side] + (x[side] - x[top]) * 0.5
    return x


def test_a_folded_laid_patch_is_untangled_on_the_fan():
    from spacemesh.repair.fill.fan import faired_fan
    from spacemesh.repair.fill.finish import onto_fan
    from spacemesh.repair.fill.lay import badly_laid

    state, own = _state_with_cap(_dragged)
    patch = state.made_by == 0
    fan, _, made = faired_fan(state.mesh, patch, DEFAULT_POLICY)
    fan_triangles, _ = triangulate_faces(faces_subset(fan, made))
    triangles, _ = triangulate_faces(faces_subset(state.mesh, patch))
    before = state.mesh.vertices
    assert badly_laid(before, triangles, fan.vertices, fan_triangles)
    assert onto_fan(state, 0, DEFAULT_POLICY) == "projected"
    assert np.array_equal(state.mesh.vertices[~own], before[~own])
    assert not badly_laid(state.mesh.vertices, triangles, fan.vertices, fan_triangles)


def test_a_patch_that_stays_folded_on_the_fan_is_replaced_by_the_fan():
    from repair_testing import assert_closed_manifold

    from spacemesh.repair.fill.finish import onto_fan

    state, _ = _state_with_cap(_dragged)
    faces_before = state.mesh.n_faces
    state_before_patch = state.made_by == 0
    assert onto_fan(state, 0, FillPolicy(relax_rounds=0)) == "fan"
    mesh = state.mesh
    assert_closed_manifold(mesh)
    made = state.made_by == 0
    assert made.any() and (state.face_source[~made] >= 0).all()  # the rest kept
    assert mesh.n_faces - made.sum() == faces_before - int((state_before_patch).sum())
    new = mesh.vertices[state.origin == 0]  # the fan's, on a thin plate over the cap
    assert len(new) >= 3 and np.abs(np.linalg.norm(new, axis=1) - 1).max() < 0.08


def test_flat_surface_is_the_least_area_triangulation_of_each_loop():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    triangles = flat_surface(square, [np.arange(4)])
    assert triangles.shape == (2, 3) and set(triangles.ravel()) == {0, 1, 2, 3}
    assert flat_surface(square, [np.arange(2)]) is None
    assert flat_surface(square, []) is None


@pytest.mark.parametrize("probing", [True, False])
def test_a_hole_whose_probes_prefer_the_flat_fill_is_laid_onto_it(probing):
    # only the flat fill is weighed, and any probe error of it below 1e9 times the
    # fairing's prefers it
    policy = FillPolicy(alternatives=("flat",), probe_margin=1e9, probe_fills=probing)
    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0]], radius=0.4)
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    flat = mesh.vertices[flat_surface(mesh.vertices, loops)]  # (T, 3, 3)
    result = _holes_filled(mesh, policy)
    new = _new_vertices(result)
    assert len(new) >= 3
    on_flat = bool(surface_distance(new, flat).max() < 1e-9)
    assert on_flat is probing  # laid onto the flat fill; else faired over the sphere
    if not probing:
        assert np.abs(np.linalg.norm(new, axis=1) - 1).max() < 0.04


def test_a_hole_that_cannot_be_laid_onto_the_flat_fill_takes_the_flat_fill():
    from spacemesh.repair.fill.lay import lay_onto

    laid: list[int] = []

    def fails_on_flat(mesh, patch, points, triangles, **options):
        laid.append(len(points))
        # the flat surface is over the mesh's own vertices; the fan's has its own
        return None if len(points) == mesh.n_vertices else lay_onto(mesh, patch, points,
                                                                     triangles, **options)

    policy = FillPolicy(alternatives=("flat",), probe_margin=1e9, lay_onto=fails_on_flat)
    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], radius=0.4)
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    result = _holes_filled(mesh, policy)
    assert laid  # the flat fill was tried
    assert {f["filled_by"] for f in result.stats.findings} == {"fallback"}
    # no vertex beyond the input's: each hole is the least-area triangulation of its loop
    assert result.mesh.n_vertices == mesh.n_vertices
    assert result.mesh.n_faces == mesh.n_faces + sum(len(loop) - 2 for loop in loops)


def test_a_fill_that_joins_its_loops_by_a_tube_is_replaced_by_one_disc_a_loop():
    from repair_testing import assert_closed_manifold

    from spacemesh.repair.fill.finish import fan_if_not_discs
    from spacemesh.repair.fill.loops import patch_euler
    from spacemesh.repair.fill.passes import Passes
    from spacemesh.topology import check_topology

    sphere = icosphere(3)
    centre_z = sphere.vertices[np.asarray(sphere.faces)].mean(axis=1)[:, 2]  # (F,)
    band = np.abs(centre_z) < 0.3  # a tube between two loops, as a handle a pass made
    own = vertices_of(sphere, band) & ~vertices_of(sphere, ~band)
    n_v, n_f = sphere.n_vertices, sphere.n_faces
    state = Passes(sphere, np.arange(n_v), np.where(band, -1, np.arange(n_f)),
                    np.full(n_f, -1), np.where(own, 0, -1), np.where(band, 0, -1))
    assert patch_euler(sphere, band) == 0 and len(patch_loops(sphere, band)) == 2
    assert fan_if_not_discs(state, 0, DEFAULT_POLICY)
    made = state.made_by == 0
    assert patch_euler(state.mesh, made) == 2  # a disc on each loop
    assert_closed_manifold(state.mesh)
    assert check_topology(state.mesh).n_components == 2  # the caps closed off each half
    # a fill of one disc a loop is left alone
    disc_state, _ = _state_with_cap(lambda x: x)
    assert not fan_if_not_discs(disc_state, 0, DEFAULT_POLICY)
