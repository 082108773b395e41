"""A marked region whose new faces still cross is grown around the crossings and
repaired again (spacemesh.repair.regrow), and the check every server runs accepts the
growth only when the stats report it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from repair_testing import (
    NoiseBackend,
    OracleBackend,
    assert_closed_manifold,
    assert_outside_identical,
    fitted_embeddings,
    make_spec,
    subset,
)

from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset
from spacemesh.repair import Region, RegionError, plan_repair, repair_mesh, verify_repair
from spacemesh.repair.regrow import (
    crossing_new_faces,
    grown_around,
    refill_crossings,
    regrow_crossings,
)

SPEC = make_spec(max_vertices=64)
REGION = {"sphere": {"center": [0.0, 0.0, 1.0], "radius": 0.6}}


@pytest.fixture(scope="module")
def sphere_and_embeddings():
    pytest.importorskip("torch")
    mesh = icosphere(1)
    return mesh, fitted_embeddings(mesh)


def _oracle_repair(mesh: PolygonMesh, embeddings, region, spec=SPEC, target=None):
    """The repair of ``region`` of ``mesh`` by networks that know ``target`` (default
    ``mesh``, whose vertices it shares; it comes back, as fit_patch=False keeps it exact),
    without regrowing."""
    target = mesh if target is None else target
    plan = plan_repair(mesh, region, spec.max_vertices)
    ids = np.concatenate([plan.patch.known, plan.cut.removed_vertices])
    backend = OracleBackend(plan.patch.to_unit(target.vertices[ids]), subset(embeddings, ids),
                            spec.schedule)
    return plan, repair_mesh(mesh, region, backend=backend, spec=spec, plan=plan,
                             fit_patch=False, regrow=False)


def _pierced(result, count: int = 1):
    """``result`` with its first ``count`` new vertices pulled through the far side of the
    sphere, so that their new faces cross kept faces there."""
    vertices = result.mesh.vertices.copy()
    kept = np.zeros(result.mesh.n_vertices, dtype=bool)
    kept[result.vertex_map[result.vertex_map >= 0]] = True
    for k, vertex in enumerate(np.flatnonzero(~kept)[:count]):
        vertices[vertex] = [0.3 * k, 0.0, -1.4]
    return replace(result, mesh=result.mesh.with_vertices(vertices))


def test_a_crossing_region_is_grown_and_repaired_again(sphere_and_embeddings):
    mesh, embeddings = sphere_and_embeddings
    plan, repaired = _oracle_repair(mesh, embeddings, REGION)
    assert len(crossing_new_faces(repaired)) == 0
    crossing = _pierced(repaired)
    pairs = crossing_new_faces(crossing)
    assert len(pairs) > 0  # the pulled vertex's faces pass through the sphere's bottom
    calls = []

    def repair(grown):
        calls.append(grown.copy())
        return _oracle_repair(mesh, embeddings, grown)[1]

    result = regrow_crossings(mesh, crossing, repair)

    assert len(calls) == 1 and len(crossing_new_faces(result)) == 0
    assert (result.region >= plan.cut.region).all()
    crossed_kept = crossing.face_source[pairs.reshape(-1)]
    assert result.region[crossed_kept[crossed_kept >= 0]].all()  # the crossed faces too
    regrown = int(result.region.sum() - plan.cut.region.sum())
    assert regrown > 0 and result.stats.fill["regrown_faces"] == regrown
    assert result.stats.fill["regrowths"] == 1
    assert result.stats.requested_faces == repaired.stats.requested_faces
    assert result.stats.grown_faces == result.stats.region_faces - result.stats.requested_faces
    assert result.stats.samplings == 2 * repaired.stats.samplings
    assert_outside_identical(mesh, result)
    assert_closed_manifold(result.mesh)
    # the server's check accepts the growth it reports, and nothing else
    assert verify_repair(plan, result) == []
    unreported = replace(result, stats=replace(result.stats, fill={}))
    assert verify_repair(plan, unreported) != []


def test_a_growth_the_plan_refuses_keeps_the_repair(sphere_and_embeddings):
    mesh, embeddings = sphere_and_embeddings
    _, repaired = _oracle_repair(mesh, embeddings, REGION)
    crossing = _pierced(repaired)

    def too_large(grown):  # a model of 8 tokens cannot take the grown region
        return _oracle_repair(mesh, embeddings, grown, spec=make_spec(max_vertices=8))[1]

    with pytest.raises(RegionError):
        too_large(crossing.region)
    assert regrow_crossings(mesh, crossing, too_large) is crossing


def test_a_growth_that_crosses_as_much_is_not_kept(sphere_and_embeddings):
    mesh, embeddings = sphere_and_embeddings
    _, repaired = _oracle_repair(mesh, embeddings, REGION)
    crossing = _pierced(repaired)

    def pierced_again(grown):  # more faces cross than before
        again = _pierced(_oracle_repair(mesh, embeddings, grown)[1], count=100)
        assert len(np.unique(crossing_new_faces(again))) > len(
            np.unique(crossing_new_faces(crossing)))
        return again

    result = regrow_crossings(mesh, crossing, pierced_again)
    assert result.mesh is crossing.mesh and np.array_equal(result.region, crossing.region)
    assert result.stats.fill["regrowths"] == 1 and result.stats.fill["regrown_faces"] == 0
    assert result.stats.samplings == 2 * repaired.stats.samplings  # its time is counted


def test_the_growth_takes_the_crossed_kept_faces_else_the_ring(sphere_and_embeddings):
    mesh, embeddings = sphere_and_embeddings
    _, repaired = _oracle_repair(mesh, embeddings, REGION)
    new = np.flatnonzero(repaired.face_source < 0)
    kept = np.flatnonzero(repaired.face_source >= 0)
    # a new face crossing a kept one: that kept face joins the region, nothing else
    grown = grown_around(mesh, repaired, np.array([[kept[-1], new[0]]]))
    assert np.array_equal(np.flatnonzero(grown & ~repaired.region),
                          [repaired.face_source[kept[-1]]])
    # new faces crossing only each other: every input face with a corner on them
    grown = grown_around(mesh, repaired, np.array([[new[0], new[1]]]))
    corners = np.unique(np.concatenate([repaired.mesh.faces[f] for f in new[:2]]))
    inputs = np.flatnonzero(np.isin(repaired.vertex_map, corners))
    touching = np.array([np.isin(face, inputs).any() for face in mesh.faces])
    assert np.array_equal(grown, repaired.region | touching)
    assert (grown & ~repaired.region).any()


@pytest.fixture(scope="module")
def filled_hole():
    """An icosphere with a hole of 6 vertices, its automatic repair ({"auto": "holes"}
    over the noise networks; 6 new vertices) and the embeddings fitted to the repaired
    mesh."""
    pytest.importorskip("torch")
    sphere = icosphere(1)
    punched = Region.sphere(sphere.vertices[0], 0.6).face_mask(sphere)
    holed, _ = faces_subset(sphere, ~punched).remove_unreferenced_vertices()
    plan = plan_repair(holed, {"auto": "holes"}, SPEC.max_vertices)
    result = repair_mesh(holed, {"auto": "holes"}, backend=NoiseBackend(), spec=SPEC,
                         plan=plan)
    assert len(crossing_new_faces(result)) == 0 and verify_repair(plan, result) == []
    assert result.stats.new_vertices == 6
    return holed, plan, result, fitted_embeddings(result.mesh)


@pytest.mark.parametrize("alone_mends", [True, False])
def test_a_crossing_fill_is_made_again_as_a_region(filled_hole, alone_mends):
    """The crossing faces alone are made again first; where that still crosses, the
    fill they belong to, whole."""
    holed, plan, result, embeddings = filled_hole
    crossing = _pierced(result)
    crossing_faces_alone = np.unique(crossing_new_faces(crossing))
    crossing_faces_alone = crossing_faces_alone[crossing.face_source[crossing_faces_alone] < 0]
    regions = []

    def repair(region):  # the fill as a marked region of the output, by networks that
        regions.append(region.copy())  # know the repaired mesh before it was pierced
        again = _oracle_repair(crossing.mesh, embeddings, region, target=result.mesh)[1]
        return again if alone_mends or len(regions) > 1 else _pierced(again, count=100)

    again = refill_crossings(crossing, repair)

    assert len(regions) == (1 if alone_mends else 2)
    assert np.array_equal(np.flatnonzero(regions[0]), crossing_faces_alone)
    if not alone_mends:
        assert np.array_equal(regions[1], crossing.face_source < 0)  # the whole fill
    assert len(crossing_new_faces(again)) == 0
    assert np.allclose(again.mesh.vertices[again.vertex_map[again.vertex_map >= 0]],
                       holed.vertices[again.vertex_map >= 0])
    assert verify_repair(plan, again) == []  # every input face comes back as it was
    assert np.array_equal(again.region, result.region)
    assert again.stats.fill["refilled_faces"] == int(regions[-1].sum())
    assert again.stats.fill["regrown_faces"] == 0
    assert again.stats.fill["refills"] == len(regions)
    assert again.stats.samplings > crossing.stats.samplings  # every run is counted
    assert again.stats.new_faces == int(np.sum(again.face_source < 0))
    assert_closed_manifold(again.mesh)


def test_a_fill_made_again_that_crosses_more_is_not_kept(filled_hole):
    _, _, result, embeddings = filled_hole
    crossing = _pierced(result)

    def worse(region):
        return _pierced(_oracle_repair(crossing.mesh, embeddings, region,
                                       target=result.mesh)[1], count=100)

    again = refill_crossings(crossing, worse)
    assert again.mesh is crossing.mesh and again.stats.fill["refills"] == 2
    assert "refilled_faces" not in again.stats.fill
    assert again.stats.samplings > crossing.stats.samplings  # their time is counted


def test_a_fill_that_cannot_be_planned_stays(filled_hole):
    _, _, result, embeddings = filled_hole
    crossing = _pierced(result)

    def too_large(region):
        return _oracle_repair(crossing.mesh, embeddings, region, spec=make_spec(8))[1]

    assert refill_crossings(crossing, too_large) is crossing
    assert refill_crossings(result, too_large) is result  # nothing crosses: not called
