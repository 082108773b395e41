"""MeshFix's fill restricted to one hole (:mod:`spacemesh.repair.fill.meshfix`)."""

from __future__ import annotations

import numpy as np
import pytest
from auto_meshes import punched

from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.repair.cut import defect_vertices
from spacemesh.repair.fill.kinds import Fairing
from spacemesh.repair.fill.meshfix import meshfix_fill
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.repair.pinched import hole_loops
from spacemesh.topology import check_topology

pytest.importorskip("pymeshfix")


def test_meshfix_fill_closes_exactly_the_loops_and_keeps_every_face():
    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], radius=0.4)
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    assert len(loops) == 2
    filled = meshfix_fill(mesh, loops[:1])  # the first hole only
    assert filled is not None
    points, triangles = filled
    assert triangles.max() < mesh.n_vertices + len(points)
    closed = PolygonMesh.from_faces(np.concatenate([mesh.vertices, points]),
                                    [*mesh.faces, *triangles])
    report = check_topology(closed)
    assert report.n_boundary_edges == len(loops[1])  # the other hole is still open
    both = meshfix_fill(mesh, loops)
    assert both is not None
    whole = PolygonMesh.from_faces(np.concatenate([mesh.vertices, both[0]]),
                                   [*mesh.faces, *both[1]])
    assert check_topology(whole).is_closed_oriented_manifold
    # every new vertex lies near the unit sphere (MeshFix's fill continues it)
    assert np.abs(np.linalg.norm(both[0], axis=1) - 1).max() < 0.1


def test_an_automatic_region_can_take_meshfix_fill_and_keeps_the_rest():
    from repair_testing import NoiseBackend, assert_closed_manifold, make_spec

    from spacemesh.repair import plan_repair, repair_mesh, verify_repair

    # every fairing replaced, so that each hole goes through MeshFix's fill
    policy = FillPolicy(meshfix_fairings=("tri-harmonic", "thin-plate", "thin-plate-uniform",
                                          "membrane", "flat", "planar"))
    assert set(policy.meshfix_fairings) == set(Fairing) - {Fairing.NONE}
    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]], radius=0.4)
    spec = make_spec()
    plan = plan_repair(mesh, {"auto": "holes"}, spec.max_vertices)
    result = repair_mesh(mesh, {"auto": "holes"}, backend=NoiseBackend(), spec=spec, plan=plan,
                         policy=policy)
    assert verify_repair(plan, result) == []
    assert_closed_manifold(result.mesh)
    assert [f["filled_by"] for f in result.stats.findings] == ["meshfix", "meshfix"]
    assert result.stats.fallback == "meshfix"
    new = result.mesh.vertices[np.unique(result.mesh.face_indices)][mesh.n_vertices:]
    assert np.abs(np.linalg.norm(new, axis=1) - 1).max() < 0.1
