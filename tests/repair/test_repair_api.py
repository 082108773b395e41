"""``repair_mesh`` end to end over numpy stand-ins of the networks."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from repair_testing import (
    NoiseBackend,
    OracleBackend,
    assert_closed_manifold,
    assert_outside_identical,
    fitted_embeddings,
    geometric_faces,
    make_spec,
    subset,
)
from test_repair_cut import open_icosphere, two_spheres_touching, with_fin

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.repair import Region, RegionError, plan_repair, repair_mesh
from spacemesh.repair.cut import outside_defects
from spacemesh.repair.fill.loops import patch_euler
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.repair.region import DEFECTS_OUTSIDE_REGION, REGION_TOO_LARGE
from spacemesh.topology import check_topology, count_vertex_fans


def test_oracle_model_gives_the_original_back():
    pytest.importorskip("torch")
    mesh = icosphere(1)
    region = {"sphere": {"center": mesh.vertices[0].tolist(), "radius": 0.6}}
    spec = make_spec(max_vertices=64)
    plan = plan_repair(mesh, region, spec.max_vertices)
    assert plan.patch.rings > 0 and len(plan.cut.removed_vertices) == 6
    ids = np.concatenate([plan.patch.known, plan.cut.removed_vertices])
    backend = OracleBackend(plan.patch.to_unit(mesh.vertices[ids]),
                            subset(fitted_embeddings(mesh), ids), spec.schedule)
    result = repair_mesh(mesh, region, backend=backend, spec=spec, plan=plan, seed=3,
                         fit_patch=False)
    assert result.stats.new_vertices == 6 and result.stats.fallback == "none"
    assert geometric_faces(result.mesh, 4) == geometric_faces(mesh, 4)
    assert_outside_identical(mesh, result)
    assert_closed_manifold(result.mesh)
    # the fit of the new vertices to the region's surface keeps the oracle's answer
    # (only its weak springs move the vertices) and everything outside
    fitted = repair_mesh(mesh, region, backend=backend, spec=spec, plan=plan, seed=3)
    assert np.array_equal(fitted.mesh.face_indices, result.mesh.face_indices)
    moved = np.abs(fitted.mesh.vertices - result.mesh.vertices).max()
    assert 0 < moved < 0.02
    assert_outside_identical(mesh, fitted)
    assert_closed_manifold(fitted.mesh)


CASES = {
    "icosphere": (lambda: icosphere(2), {"sphere": {"center": [0, 0, 1], "radius": 0.5}}),
    "torus": (lambda: torus_grid(16, 8, triangulate_every=3),
              {"box": {"min": [2, -0.6, -2], "max": [4, 0.6, 2]}}),
    "cube": (cube_quads, {"faces": [0]}),
    "cube-band": (cube_quads, {"faces": [0, 1, 2, 3]}),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_any_model_keeps_the_outside_and_closes_the_hole(name):
    make, region = CASES[name]
    mesh = make()
    spec = make_spec(max_vertices=64)
    for seed in range(3):
        result = repair_mesh(mesh, region, backend=NoiseBackend(seed), spec=spec, seed=seed)
        assert_outside_identical(mesh, result)
        assert_closed_manifold(result.mesh)
        stats = result.stats
        assert stats.new_faces == result.mesh.n_faces - (mesh.n_faces - stats.region_faces)
        assert stats.steps == 8 and stats.method == "ddim" and stats.seed == seed
        assert set(stats.timings) >= {"cut", "patch", "encoder", "sampler", "connectivity",
                                      "splice", "total"}
        assert stats.to_dict()["new_vertices"] == stats.new_vertices


def test_same_seed_same_mesh_and_progress_is_reported():
    mesh = icosphere(2)
    region = Region.sphere([0, 0, 1], 0.5)
    spec = make_spec()
    done = []
    a = repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec, seed=7, steps=5,
                    progress=lambda d, t: done.append((d, t)))
    b = repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec, seed=7, steps=5)
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert np.array_equal(a.mesh.face_indices, b.mesh.face_indices)
    assert done == [(i, 5) for i in range(1, 6)] and a.stats.steps == 5
    with pytest.raises(ValueError, match="steps"):
        repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec, steps=0)
    with pytest.raises(ValueError, match="sampler"):
        repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec, method="euler")


def test_inward_faces_are_read_with_reversed_orders():
    mesh = icosphere(2)
    inward = PolygonMesh.from_faces(mesh.vertices, [f[::-1] for f in mesh.faces])
    result = repair_mesh(inward, {"vertices": [0]}, backend=NoiseBackend(), spec=make_spec())
    assert result.stats.flipped_orientation
    assert_outside_identical(inward, result)
    assert_closed_manifold(result.mesh)


def test_large_mesh_is_repaired_through_a_patch():
    mesh = torus_grid(500, 400)  # 200,000 quads
    spec = make_spec(max_vertices=64)
    backend = NoiseBackend()
    start = time.perf_counter()
    result = repair_mesh(mesh, Region.sphere(mesh.vertices[1234], 0.03), backend=backend,
                         spec=spec)
    seconds = time.perf_counter() - start
    stats = result.stats
    assert stats.known_vertices <= spec.max_vertices - 8 and stats.patch_faces < 200
    assert 0 < stats.region_faces < 30
    assert seconds < 20, stats.timings
    assert_outside_identical(mesh, result)
    assert outside_defects(result.mesh, np.zeros(result.mesh.n_faces, dtype=bool)) == []
    near = np.unique(result.mesh.face_indices[result.mesh.face_offsets[
        int((result.face_source >= 0).sum())]:])
    assert near.size > 0


def test_too_large_a_region_is_refused_before_any_network_runs():
    mesh = icosphere(3)
    backend = NoiseBackend()
    with pytest.raises(RegionError) as caught:
        repair_mesh(mesh, Region.box([-1, -1, -0.1], [1, 1, 0.1]), backend=backend,
                    spec=make_spec(max_vertices=64))
    assert caught.value.kind == REGION_TOO_LARGE
    assert caught.value.details["boundary_vertices"] > 56
    assert backend.calls == {"encode": 0, "denoise": 0, "connect": 0}


def test_open_and_non_manifold_inputs_are_repaired_when_the_region_covers_them():
    spec = make_spec()
    opened, _ = open_icosphere()
    finned, u = with_fin()
    pinched = two_spheres_touching()
    pinch = np.flatnonzero(count_vertex_fans(pinched) > 1)
    for mesh in (opened, finned, pinched):
        assert not check_topology(mesh).is_closed_oriented_manifold
    for mesh, region in ((opened, Region.sphere(opened.vertices[0], 0.35)),
                         (finned, Region.sphere(finned.vertices[u], 0.4)),
                         (pinched, Region.from_vertices(pinch))):
        result = repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec)
        assert_outside_identical(mesh, result)
        assert_closed_manifold(result.mesh)


def test_defects_outside_the_region_are_listed():
    mesh, _ = open_icosphere()
    with pytest.raises(RegionError) as caught:
        repair_mesh(mesh, Region.sphere(-mesh.vertices[0], 0.3), backend=NoiseBackend(),
                    spec=make_spec())
    assert caught.value.kind == DEFECTS_OUTSIDE_REGION
    assert caught.value.details["defects"][0]["kind"] == "open-boundary"


def test_repair_never_imports_torch():
    script = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'torch' or name.startswith('torch.'):\n"
        "            raise ImportError('torch is blocked')\n"
        "sys.meta_path.insert(0, Block())\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from repair_testing import NoiseBackend, make_spec\n"
        "from spacemesh.examples import icosphere\n"
        "from spacemesh.repair import repair_mesh\n"
        "r = repair_mesh(icosphere(2), {'vertices': [0]}, backend=NoiseBackend(),"
        " spec=make_spec())\n"
        "assert 'torch' not in sys.modules\n"
        "print('ok', r.mesh.n_faces)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith("ok")


def test_a_fill_with_a_handle_is_sampled_again():
    mesh, region = icosphere(3), {"vertices": [0]}
    spec = make_spec()
    calls: list[int] = []  # each fill's (the region's own is read by patch_euler itself)

    def handle_first(surface, faces):
        calls.append(patch_euler(surface, faces))
        return calls[-1] - 2 if len(calls) == 1 else calls[-1]  # the first fill: a handle

    again = repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec, seed=7,
                        policy=FillPolicy(euler=handle_first))
    assert len(calls) == 2  # sampled once more with the seed's next stream
    assert_closed_manifold(again.mesh)
    assert again.stats.samplings == 2 and again.stats.handles_added == 0
    first = repair_mesh(mesh, region, backend=NoiseBackend(), spec=spec, seed=7)
    assert not np.array_equal(first.mesh.vertices, again.mesh.vertices)
    assert check_topology(again.mesh).euler_characteristic == 2
    assert first.stats.samplings == 1 and first.stats.handles_added == 0


def test_of_samplings_that_all_add_handles_the_one_with_fewest_is_kept():
    mesh, region = icosphere(3), {"vertices": [0]}
    handles = iter([2, 1, 2])  # the three samplings (the region itself has none)
    spliced = []  # each sampling's spliced mesh, as the fill's Euler characteristic reads it

    def euler(surface, faces):
        spliced.append(surface)
        return patch_euler(surface, faces) - 2 * next(handles)

    result = repair_mesh(mesh, region, backend=NoiseBackend(), spec=make_spec(), seed=7,
                         fit_patch=False, policy=FillPolicy(euler=euler))
    assert result.stats.samplings == 3 and result.stats.handles_added == 1
    kept, last = spliced[1], spliced[2]
    assert not np.array_equal(kept.vertices, last.vertices)  # the samplings differ
    assert np.array_equal(result.mesh.vertices, kept.vertices)
    assert np.array_equal(result.mesh.face_indices, kept.face_indices)


def test_a_handle_in_every_sampling_is_reported():
    import spacemesh.repair.api as api

    mesh, region = icosphere(3), {"vertices": [0]}
    calls: list[int] = []

    def always_a_handle(surface, faces):
        calls.append(patch_euler(surface, faces))
        return calls[-1] - 2  # every fill: one handle

    result = repair_mesh(mesh, region, backend=NoiseBackend(), spec=make_spec(), seed=7,
                         policy=FillPolicy(euler=always_a_handle))
    assert len(calls) == api.TOPOLOGY_ATTEMPTS
    assert result.stats.samplings == api.TOPOLOGY_ATTEMPTS
    assert result.stats.handles_added == 1
    assert result.stats.to_dict()["handles_added"] == 1
