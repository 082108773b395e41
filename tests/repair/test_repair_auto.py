"""Automatic regions (``{"auto": "holes" | "defects" | "all"}``) and the growth bound,
with the untrained-looking stand-in model: whatever it predicts, every hole and defect
must come back closed, oriented and manifold, the faces outside the regions unchanged."""

from __future__ import annotations

import numpy as np
import pytest
from auto_meshes import (
    cylinder,
    grid_disk,
    hemisphere,
    moebius,
    pinched_annulus,
    pinched_spheres,
    punched,
    touching_holes,
    with_degenerate_face,
    with_fin,
)
from repair_testing import NoiseBackend, assert_closed_manifold, assert_outside_identical, make_spec

from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.repair import (
    Region,
    RegionError,
    parse_region,
    plan_repair,
    repair_mesh,
    verify_repair,
)
from spacemesh.repair.auto import AutoPlan, wedge_size
from spacemesh.repair.cut import defect_vertices
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.repair.findings import find_issues
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.repair.orient import orient_faces, reverse_faces
from spacemesh.repair.pinched import hole_loops
from spacemesh.repair.unzip import unpaired_faces, unzip_defects
from spacemesh.topology import check_topology

SPEC = make_spec()


def run(mesh, region, **kwargs):
    """Plan, repair and check that nothing beyond the planned regions changed."""
    plan = kwargs.pop("plan", None) or plan_repair(
        mesh, region, SPEC.max_vertices, max_growth=kwargs.pop("max_growth", None))
    result = repair_mesh(mesh, region, backend=NoiseBackend(), spec=SPEC, plan=plan, **kwargs)
    assert verify_repair(plan, result) == []
    return result


# ---------------------------------------------------------------------- the region form
def test_auto_region_json_round_trip_and_bad_values():
    for mode in ("holes", "defects", "all"):
        region = parse_region({"auto": mode})
        assert region.is_auto and region.mode == mode
        assert region.to_dict() == {"auto": mode}
    for bad in ({"auto": "everything"}, {"auto": 1}, {"auto": "holes", "faces": [1]}):
        with pytest.raises(RegionError) as info:
            parse_region(bad)
        assert info.value.kind == "invalid-region"


def test_auto_face_mask_selects_the_ring_of_every_hole():
    mesh = punched(icosphere(3), [[0, 0, 1], [0, 0, -1]])
    mask = Region.auto("holes").face_mask(mesh)
    open_vertices = defect_vertices(mesh)
    touching = np.zeros(mesh.n_faces, dtype=bool)
    touching[mesh.face_of_corner[open_vertices[mesh.face_indices]]] = True
    assert np.array_equal(mask, touching) and mask.any() and not mask.all()
    assert not Region.auto("defects").face_mask(mesh).any()  # holes are not defects


# ---------------------------------------------------------------------- holes
def test_holes_are_filled_closed_and_the_rest_is_unchanged():
    mesh = punched(icosphere(3), [[0, 0, 1], [0, 0, -1], [1, 0, 0]])
    assert not check_topology(mesh).is_closed_oriented_manifold
    result = run(mesh, {"auto": "holes"}, seed=2)  # the stand-in fills all three
    assert_closed_manifold(result.mesh)
    assert_outside_identical(mesh, result)
    stats = result.stats
    assert stats.auto_region == "holes" and stats.passes == 3 and stats.findings_total == 3
    assert [f["kind"] for f in stats.findings] == ["hole"] * 3
    assert all(f["filled_by"] == "model" and f["action"] == "filled" for f in stats.findings)
    assert sorted(f["region"] for f in stats.findings) == [0, 1, 2]
    for region in stats.regions:  # filled in place: the ring is kept
        assert region["strategy"] == "in-place" and region["passes"] == 1
        assert region["requested_faces"] > 0 and region["region_faces"] == 0
    assert stats.region_faces == 0 and result.mesh.n_faces > mesh.n_faces
    # the same seed gives the same mesh
    again = run(mesh, {"auto": "holes"}, seed=2)
    assert np.array_equal(again.mesh.vertices, result.mesh.vertices)


def test_a_hole_too_large_for_one_pass_is_filled_in_wedges():
    # the flat disk over the equator would be MeshFix's fill, and the stand-in model's
    # wedges cross (a crossing fill would give way to the fan); the wedges are tested here
    policy = FillPolicy(meshfix_fairings=(), unchecked_fills=False, uncrossed_fills=False)
    mesh = hemisphere(4)  # one loop of 96 vertices; the stand-in model holds 56
    plan = plan_repair(mesh, {"auto": "holes"}, SPEC.max_vertices)
    assert isinstance(plan, AutoPlan)
    [region] = plan.regions
    assert region.strategy == "in-place"
    result = run(mesh, {"auto": "holes"}, plan=plan, policy=policy)
    assert_closed_manifold(result.mesh)
    assert_outside_identical(mesh, result)
    stats = result.stats
    [hole] = stats.findings
    assert hole["size"] == 96 and hole["filled_by"] in ("model", "model-and-fallback")
    assert 1 <= stats.passes <= -(-96 // wedge_size(SPEC.max_vertices))
    assert stats.region_faces == 0  # every input face stays
    assert result.mesh.n_faces > mesh.n_faces


@pytest.mark.parametrize("build, distance", [
    (lambda: punched(icosphere(4), [[0, 0, 1], [0.6, 0, -0.8]], radius=0.5),
     lambda v: np.linalg.norm(v, axis=1) - 1),
    (lambda: punched(cylinder(24, 12), [[1, 0, 0]], radius=0.6),
     lambda v: np.linalg.norm(v[:, :2], axis=1) - 1),
])
def test_filled_holes_continue_the_surface_around_them(build, distance):
    mesh = build()
    result = run(mesh, {"auto": "holes"}, seed=1)
    assert_closed_manifold(result.mesh)
    assert_outside_identical(mesh, result)
    kept = np.zeros(result.mesh.n_vertices, dtype=bool)
    kept[result.vertex_map[result.vertex_map >= 0]] = True
    new = result.mesh.vertices[~kept]
    assert len(new) >= 10  # refined to the density around the holes
    assert np.abs(distance(new)).max() < 0.04, np.abs(distance(new)).max()
    # without the fairing the patch stays on the flat fans, off the surface
    flat = run(mesh, {"auto": "holes"}, seed=1, fit_patch=False)
    kept = np.zeros(flat.mesh.n_vertices, dtype=bool)
    kept[flat.vertex_map[flat.vertex_map >= 0]] = True
    assert np.abs(distance(flat.mesh.vertices[~kept])).max() > 0.1


def test_an_open_disk_whose_ring_is_most_of_the_mesh_is_closed():
    mesh = grid_disk(6)
    result = run(mesh, {"auto": "holes"})
    assert_closed_manifold(result.mesh)
    assert_outside_identical(mesh, result)


def test_a_hole_at_a_vertex_with_a_closed_fan_is_rebuilt_with_its_ring():
    """Filling the loop alone would leave the vertex pinched (the closed fan of the
    other sphere stays): it is a finding of its own, and its region gets the model."""
    mesh = pinched_spheres()
    [shared] = np.flatnonzero(FaceSubset.of(mesh, np.arange(mesh.n_faces))
                              .fan_counts(mesh.n_vertices) > 1)
    drop = np.zeros(mesh.n_faces, dtype=bool)
    drop[mesh.face_of_corner[mesh.face_indices == shared][0]] = True
    from auto_meshes import without_faces

    opened = without_faces(mesh, drop)
    kinds = {f.kind for f in find_issues(opened, "holes")}
    assert kinds == {"hole", "pinched-vertices"}
    result = run(opened, {"auto": "holes"})
    assert_closed_manifold(result.mesh)
    assert [r["strategy"] for r in result.stats.regions] == ["model"]


@pytest.mark.parametrize("build, loops", [(touching_holes, [5, 6]),
                                           (pinched_annulus, [9, 9])])
def test_loops_touching_at_a_vertex_are_split_there_and_filled_in_place(build, loops):
    """Two loops through one vertex (two holes touching), and one loop through a vertex
    twice (an annulus whose island touches the rest): each gap between the vertex's two
    fans becomes the corner of one simple loop (the second case split by a new edge), and
    filling them joins the fans into one disc, no input face changed."""
    mesh = build()
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    [pinch] = np.flatnonzero(sub.fan_counts(mesh.n_vertices) > 1)
    [hole] = find_issues(mesh, "holes")
    split = hole_loops(mesh, hole.vertices)
    assert split is not None and sorted(len(loop) for loop in split) == loops
    assert all(len(set(loop.tolist())) == len(loop) for loop in split)
    assert sum(int(pinch) in loop.tolist() for loop in split) == 2
    result = run(mesh, {"auto": "holes"})
    assert_closed_manifold(result.mesh)
    assert_outside_identical(mesh, result)
    assert [r["strategy"] for r in result.stats.regions] == ["in-place"]


def test_a_closed_mesh_has_nothing_to_repair():
    with pytest.raises(RegionError) as info:
        plan_repair(icosphere(2), {"auto": "all"}, SPEC.max_vertices)
    assert info.value.kind == "empty-region" and "nothing to repair" in str(info.value)


# ---------------------------------------------------------------------- defects
@pytest.mark.parametrize("build, mode, kinds", [
    (lambda: with_fin(icosphere(2)), "all", {"hole", "non-manifold-edges"}),
    (lambda: with_degenerate_face(icosphere(2)), "defects", {"degenerate-faces"}),
    (pinched_spheres, "defects", {"pinched-vertices"}),
])
def test_defects_are_rebuilt_into_a_closed_manifold(build, mode, kinds):
    mesh = build()
    found = {f.kind for f in find_issues(mesh, mode)}
    assert kinds <= found
    result = run(mesh, {"auto": mode})
    assert_closed_manifold(result.mesh)
    assert_outside_identical(mesh, result)
    assert kinds <= {f["kind"] for f in result.stats.findings}
    assert all(f["action"] == ("filled" if f["kind"] == "hole" else "rebuilt")
               for f in result.stats.findings)


def test_holes_alone_leave_other_defects_refused():
    mesh = with_fin(punched(icosphere(3), [[0, 0, -1]]))
    with pytest.raises(RegionError) as info:
        plan_repair(mesh, {"auto": "defects"}, SPEC.max_vertices)
    # the fin's own open edges are a hole; the defects region does not cover the holes
    assert info.value.kind == "defects-outside-region"
    assert info.value.details["findings"]
    result = run(mesh, {"auto": "all"})
    assert_closed_manifold(result.mesh)


# ---------------------------------------------------------------------- orientation
def test_moebius_strip_is_refused_as_non_orientable():
    with pytest.raises(RegionError) as info:
        plan_repair(moebius(), {"auto": "holes"}, SPEC.max_vertices)
    assert info.value.kind == "non-orientable" and "Moebius" in str(info.value)
    assert info.value.details["faces"]


def test_flipped_faces_are_reoriented_and_inside_out_meshes_flipped_whole():
    ico = icosphere(2)
    cap = np.zeros(ico.n_faces, dtype=bool)
    cap[:30] = True
    oriented, reversed_ = orient_faces(reverse_faces(ico, cap))
    assert np.array_equal(reversed_, cap)
    assert np.array_equal(oriented.face_indices, ico.face_indices)
    result = run(reverse_faces(ico, cap), {"auto": "defects"})
    assert result.stats.reversed_faces == 30 and not result.stats.flipped_mesh
    assert_closed_manifold(result.mesh)
    inside_out = reverse_faces(ico, np.ones(ico.n_faces, dtype=bool))
    result = run(inside_out, {"auto": "all"})
    assert result.stats.flipped_mesh and result.stats.reversed_faces == ico.n_faces
    assert np.array_equal(result.mesh.face_indices, ico.face_indices)


# ---------------------------------------------------------------------- growth bound
def _pinched_pair(mesh):
    """Two faces that touch at one vertex only (a region that must grow)."""
    v = 0
    around = np.flatnonzero(np.isin(np.arange(mesh.n_faces),
                                    mesh.face_of_corner[mesh.face_indices == v]))
    faces = [set(mesh.faces[f].tolist()) for f in around]
    for i, a in enumerate(around):
        for j, b in enumerate(around):
            if i < j and faces[i] & faces[j] == {v}:
                return [int(a), int(b)]
    raise AssertionError("no pinched pair")


def test_growth_beyond_the_share_is_refused_and_max_growth_overrides_it():
    mesh = icosphere(1)  # 80 faces; the pinched pair grows to the 5 faces around vertex 0
    region = {"faces": _pinched_pair(mesh)}
    plan = plan_repair(mesh, region, SPEC.max_vertices)  # 6% <= 25%
    assert plan.cut.n_grown > 0
    with pytest.raises(RegionError) as info:
        plan_repair(mesh, region, SPEC.max_vertices, max_growth=0.05)
    error = info.value
    assert error.kind == "region-growth-exceeded"
    assert error.details["share"] == pytest.approx(plan.cut.region.sum() / 80, abs=1e-4)
    assert error.details["max_growth"] == 0.05 and "max_growth" in str(error)
    result = run(mesh, region, max_growth=0.5)
    assert result.stats.grown_faces == plan.cut.n_grown
    assert result.stats.region_share == pytest.approx(plan.cut.region.sum() / 80, abs=1e-4)
    with pytest.raises(ValueError, match="max_growth"):
        plan_repair(mesh, region, SPEC.max_vertices, max_growth=1.5)


def test_a_marked_region_that_does_not_grow_is_never_refused_for_its_size():
    mesh = icosphere(1)
    plan = plan_repair(mesh, {"sphere": {"center": [0, 0, 1], "radius": 1.0}},
                       SPEC.max_vertices, max_growth=0.0)
    assert plan.cut.n_grown == 0 and plan.cut.region.sum() > 0.25 * mesh.n_faces


# ---------------------------------------------------------------------- command line
@pytest.fixture()
def fake_model(monkeypatch):
    from spacemesh.runtime import MeshGenerator

    def from_repository(cls, path=None, **kwargs):
        return cls(NoiseBackend(), make_spec(), name="noise")

    monkeypatch.setattr(MeshGenerator, "from_repository", classmethod(from_repository))


def _cli(args):
    from typer.testing import CliRunner

    from spacemesh.cli import _register
    from spacemesh.cli.common import app

    _register()
    return CliRunner().invoke(app, ["repair", *args])


@pytest.mark.parametrize("flags, mode", [(["--holes"], "holes"), (["--defects"], "defects"),
                                         (["--auto"], "all"), (["--holes", "--defects"], "all")])
def test_cli_flags_map_to_the_auto_forms(flags, mode):
    from spacemesh.cli.repair import region_from_options

    options = {f.lstrip("-"): True for f in flags}
    assert region_from_options(None, None, None, None, **options) == {"auto": mode}


def test_cli_fills_holes(fake_model, tmp_path):
    import json

    from spacemesh.io import load_mesh, save_mesh

    source, out = tmp_path / "open.obj", tmp_path / "closed.obj"
    mesh = punched(icosphere(3), [[0, 0, 1], [0, 0, -1]])
    save_mesh(mesh, source)
    result = _cli([str(source), "--holes", "-o", str(out), "--json", "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["auto_region"] == "holes" and summary["findings_total"] == 2
    assert_closed_manifold(load_mesh(out))
    result = _cli([str(source), "--auto", "-o", str(out), "--no-progress"])
    assert result.exit_code == 0 and "found 2 hole" in result.output


@pytest.mark.parametrize("args, message", [
    (["--holes", "--faces", "1"], "do not combine with --faces"),
    (["--auto", "--sphere", "0,0,1,0.3"], "do not combine with --sphere"),
    (["--defects"], "empty-region"),
    (["--faces", "0,1", "--max-growth", "2"], "max-growth"),
])
def test_cli_auto_errors_are_one_line(fake_model, tmp_path, args, message):
    from spacemesh.io import save_mesh

    source = tmp_path / "ico.obj"
    save_mesh(punched(icosphere(2), [[0, 0, 1]]), source)
    result = _cli([str(source), *args, "-o", str(tmp_path / "o.obj")])
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output


def test_cli_refuses_a_moebius_strip(fake_model, tmp_path):
    from spacemesh.io import save_mesh

    source = tmp_path / "moebius.obj"
    save_mesh(moebius(), source)
    result = _cli([str(source), "--holes", "-o", str(tmp_path / "o.obj")])
    assert result.exit_code == 2 and "non-orientable" in result.output
    assert len(result.output.strip().splitlines()) == 1


# ---------------------------------------------------------------------- defects beside holes
def test_unzip_splits_a_fin_off_and_keeps_every_corner_in_place():
    mesh = with_fin(icosphere(2))
    fin = find_issues(mesh, "defects")
    marked = np.zeros(mesh.n_vertices, dtype=bool)
    for f in fin:
        marked[f.vertices] = True
    out = unzip_defects(mesh, marked)
    assert out.n_vertices > mesh.n_vertices
    assert np.array_equal(out.face_offsets, mesh.face_offsets)
    assert np.array_equal(out.vertices[out.face_indices], mesh.vertices[mesh.face_indices])
    sub = FaceSubset.of(out, np.arange(out.n_faces))
    assert (sub.edge_count <= 2).all() and not unpaired_faces(out).any()
    assert {f.kind for f in find_issues(out, "all")} == {"hole"}


@pytest.mark.parametrize("mode", ["all", "holes"])
def test_a_fin_on_a_large_hole_is_split_off_then_the_holes_are_filled_in_place(mode):
    mesh = hemisphere(4)
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    rim = np.zeros(mesh.n_vertices, dtype=bool)
    rim[sub.halfedges[sub.edge_count[sub.edge] == 1].reshape(-1)] = True
    a, b = next((int(a), int(b)) for a, b in mesh.edges if rim[a] != rim[b])
    tip = mesh.vertices[a] + mesh.vertices[b] - 0.5 * mesh.vertices[a:a + 1].sum(axis=0)
    mesh = PolygonMesh.from_faces(np.vstack([mesh.vertices, tip]),
                                  [*mesh.faces, np.array([a, b, mesh.n_vertices])])
    # as one region the fin and the loop beside it are more than the model holds
    plan = plan_repair(mesh, {"auto": mode}, SPEC.max_vertices)
    assert isinstance(plan, AutoPlan) and plan.split
    assert all(r.strategy == "in-place" for r in plan.regions)
    result = run(mesh, {"auto": mode}, plan=plan)
    assert_closed_manifold(result.mesh)
    assert not result.region.any()  # every face kept, the fin's vertices split
    out = result.mesh
    n = mesh.face_offsets[-1]
    assert np.array_equal(out.vertices[out.face_indices[:n]], mesh.vertices[mesh.face_indices])
    actions = {f["kind"]: f["action"] for f in result.stats.findings}
    assert actions["non-manifold-edges"] == "split" and actions["hole"] == "filled"


def test_an_automatic_fill_with_a_handle_takes_the_fan_and_reports_none():
    import spacemesh.repair.api as api
    from spacemesh.repair.fill.loops import patch_euler

    calls: list[int] = []

    def every_fill_a_handle(surface, faces):
        # each sampling of a pass (the region's own is read by patch_euler itself), then
        # the region's fill once the passes are done
        calls.append(patch_euler(surface, faces))
        return calls[-1] - 2

    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0]], radius=0.4)
    result = run(mesh, {"auto": "holes"}, policy=FillPolicy(euler=every_fill_a_handle))
    assert_closed_manifold(result.mesh)
    assert check_topology(result.mesh).euler_characteristic == 2
    stats = result.stats
    assert [f["filled_by"] for f in stats.findings] == ["fallback"]
    assert stats.samplings == api.TOPOLOGY_ATTEMPTS * stats.passes  # each pass sampled 3 times
    # every sampling, then the region's fill (one region): the fill was read after them
    assert len(calls) == stats.samplings + 1
    assert stats.handles_added == 0  # the fan replaced the handled fills
