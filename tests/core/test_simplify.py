"""Edge collapses with the points' quadrics (spacemesh.geometry.simplify): the count asked
for, a closed oriented manifold with the same pieces and genus, no crossing faces, faces
that are the input's reduced by collapses, and creases kept where the points have them."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import icosphere, torus_grid
from spacemesh.geometry.intersections import self_intersection_fraction
from spacemesh.geometry.simplify import point_quadrics, simplify
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface
from spacemesh.topology import surface_topology
from tests.validity import assert_valid_mesh


def _points(mesh: PolygonMesh, count: int = 3000, seed: int = 0):
    return sample_surface(mesh, count, np.random.default_rng(seed))


def _triangulated(mesh: PolygonMesh) -> PolygonMesh:
    from spacemesh.primitives import triangles_of

    tri, _ = triangles_of(mesh)
    return PolygonMesh(mesh.vertices, tri.reshape(-1), np.arange(0, 3 * len(tri) + 1, 3))


def _canonical(face) -> tuple[int, ...]:
    """A face as a tuple starting at its smallest vertex (orientation kept)."""
    face = [int(v) for v in face]
    k = face.index(min(face))
    return tuple(face[k:] + face[:k])


def _check(source: PolygonMesh, result) -> None:
    out = result.mesh
    assert_valid_mesh(out)
    before, after = surface_topology(source), surface_topology(out)
    assert (after.pieces, after.genus) == (before.pieces, before.genus)
    assert self_intersection_fraction(out) == 0.0
    # every face is an input face with its vertices mapped through the collapses
    mapped = {_canonical(result.vertex_map[f]) for f in source.face_indices.reshape(-1, 3)}
    assert {_canonical(f) for f in out.face_indices.reshape(-1, 3)} <= mapped


def test_an_ellipsoid_is_collapsed_to_the_count_asked_for():
    mesh = icosphere(4)
    mesh = mesh.with_vertices(mesh.vertices * [1.0, 0.6, 0.3])
    points, _ = _points(mesh)
    result = simplify(mesh, points, target_vertices=150)
    assert result.mesh.n_vertices == 150 and result.stats["collapsed"] == mesh.n_vertices - 150
    _check(mesh, result)
    # the surface stays on the points: every point within 2% of the diagonal of the mesh
    from spacemesh.geometry import fit_report

    assert fit_report(result.mesh, points).points_to_mesh_mean_rel < 0.004


@pytest.mark.parametrize("target", [40, 12])
def test_a_torus_keeps_its_genus_and_two_spheres_their_pieces(target):
    torus = _triangulated(torus_grid(24, 12))
    points, _ = _points(torus)
    result = simplify(torus, points, target_vertices=target)
    _check(torus, result)
    assert surface_topology(result.mesh).genus == 1
    sphere = icosphere(3)
    shifted = sphere.vertices + np.array([3.0, 0.0, 0.0])
    two = PolygonMesh(np.concatenate([sphere.vertices, shifted]),
                      np.concatenate([sphere.face_indices,
                                      sphere.face_indices + sphere.n_vertices]),
                      np.arange(0, 6 * sphere.n_faces + 1, 3))
    points, _ = _points(two)
    result = simplify(two, points, target_vertices=target)
    _check(two, result)
    assert surface_topology(result.mesh).pieces == 2
    assert result.mesh.n_vertices >= 8  # no piece below a tetrahedron


def test_the_points_planes_keep_a_cubes_corners():
    """A finely tessellated cube whose points lie on its faces collapses onto its
    corners: the quadrics come from the points, so creases cost and stay."""
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0)).subdivide().subdivide().subdivide()
    mesh = PolygonMesh.from_faces(np.asarray(box.vertices), np.asarray(box.faces))
    points, normals = _points(mesh, 6000)  # the planes of the faces under the points
    result = simplify(mesh, points, normals, target_vertices=30)
    _check(mesh, result)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    nearest = np.linalg.norm(corners[:, None] - result.mesh.vertices[None], axis=2).min(axis=1)
    assert nearest.max() < 0.02  # every corner kept (2 is the edge length)
    # and the faces stay on the cube's planes
    assert np.abs(result.mesh.vertices).max(axis=1).min() > 0.98


def test_point_quadrics_measure_squared_distances_to_the_points_planes():
    vertices = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    points = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.0], [0.2, -0.1, 0.0]])
    normals = np.tile([0.0, 0.0, 2.0], (3, 1))  # not unit: normalised
    quadrics = point_quadrics(vertices, points, normals)
    h = np.array([0.3, -0.2, 0.5, 1.0])
    assert h @ quadrics[0] @ h == pytest.approx(3 * 0.5**2)
    assert np.all(quadrics[1] == 0)  # no point is nearest to the far vertex


def test_small_or_polygon_meshes_come_back_unchanged():
    mesh = icosphere(1)
    points, _ = _points(mesh)
    result = simplify(mesh, points, target_vertices=mesh.n_vertices)
    assert result.mesh is mesh and result.stats["collapsed"] == 0
    from spacemesh.examples import cube_quads

    cube = cube_quads()
    assert simplify(cube, _points(cube)[0], target_vertices=4).mesh is cube


def _fine_box() -> PolygonMesh:
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0)).subdivide().subdivide()
    return PolygonMesh.from_faces(np.asarray(box.vertices), np.asarray(box.faces))


@pytest.mark.parametrize("max_error", [1e-4, 1e-3, 1e-2])
def test_stop_at_error_makes_no_collapse_over_it(max_error):
    """``max_error``: no collapse whose error (a mean squared distance from the planes
    its vertex gathered) exceeds it, whatever the count; on an ellipsoid (no two faces
    coplanar) a larger error allows more collapses."""
    mesh = icosphere(3)
    mesh = mesh.with_vertices(mesh.vertices * [1.0, 0.6, 0.3])
    result = simplify(mesh, None, max_error=max_error)
    _check(mesh, result)
    assert 0 < result.stats["collapsed"] < mesh.n_vertices - 4
    assert 0 < result.stats["max_error"] <= max_error
    # the surface stays within about the error's distance of where it was
    from spacemesh.geometry import fit_report

    points, _ = _points(mesh)
    assert fit_report(result.mesh, points).points_to_mesh_p95 < 3 * np.sqrt(max_error)
    fewer = simplify(mesh, None, max_error=max_error / 10)
    assert fewer.stats["collapsed"] < result.stats["collapsed"]


def test_stop_at_error_collapses_a_box_onto_its_corners_and_no_further():
    mesh = _fine_box()
    result = simplify(mesh, None, max_error=1e-9)  # flat collapses cost nothing
    _check(mesh, result)
    assert result.mesh.n_vertices == 8 and result.stats["max_error"] <= 1e-9
    assert np.allclose(np.abs(result.mesh.vertices), 1.0)
    # the points' planes (estimated normals, blurred at the creases) cost more there
    points, _ = _points(mesh)
    assert simplify(mesh, points, max_error=1e-9).mesh.n_vertices > 8


def test_stop_at_distance_keeps_the_points_within_it():
    """``max_distance``: the mesh returned keeps the mean distance from the points
    within it (measured as the fit report does), and a larger one allows more
    collapses; below the input's own distance nothing collapses."""
    from spacemesh.geometry.report import points_to_mesh_mean

    max_distance = 0.01
    mesh = icosphere(3)
    mesh = mesh.with_vertices(mesh.vertices * [1.0, 0.6, 0.3])
    points, _ = _points(mesh, 1500)
    result = simplify(mesh, points, max_distance=max_distance)
    _check(mesh, result)
    assert 0 < result.stats["collapsed"] < mesh.n_vertices - 4
    assert points_to_mesh_mean(result.mesh, points) <= max_distance
    assert result.stats["mean_distance"] == pytest.approx(
        points_to_mesh_mean(result.mesh, points))
    assert simplify(mesh, points, max_distance=2 * max_distance).mesh.n_vertices < (
        result.mesh.n_vertices)
    unchanged = simplify(mesh, points, max_distance=1e-9)
    assert unchanged.mesh is mesh and unchanged.vertex_map is None
    with pytest.raises(ValueError, match="points"):
        simplify(mesh, None, max_distance=max_distance)


def test_an_open_mesh_keeps_its_boundary():
    mesh = _fine_box()
    centres = mesh.vertices[mesh.face_indices.reshape(-1, 3)].mean(axis=1)
    keep = centres[:, 2] < 0.99  # the top face removed: a boundary loop
    tri = mesh.face_indices.reshape(-1, 3)[keep]
    used = np.unique(tri)
    index = np.full(mesh.n_vertices, -1)
    index[used] = np.arange(len(used))
    opened = PolygonMesh(mesh.vertices[used], index[tri].reshape(-1),
                         np.arange(0, 3 * len(tri) + 1, 3))
    result = simplify(opened, None, max_error=1e-9)
    assert_valid_mesh(result.mesh, open_surface=True)
    rim = np.isclose(opened.vertices[:, 2], 1.0)
    kept = {tuple(v) for v in result.mesh.vertices}
    assert all(tuple(v) in kept for v in opened.vertices[rim])  # every rim vertex stays
    assert result.mesh.n_vertices < opened.n_vertices - 20


# ---------------------------------------------------------------- identity with the
# straightforward forms of the hot paths (the faster ones must answer byte for byte alike)


def _noisy_ellipsoid(seed: int) -> PolygonMesh:
    """A noisy flattened icosphere (162 vertices): its collapses are often refused for
    crossings."""
    mesh = icosphere(2)
    rng = np.random.default_rng(seed)
    return mesh.with_vertices(mesh.vertices * [1.0, 0.5, 0.25]
                              + rng.normal(scale=0.05, size=mesh.vertices.shape))


def _reference_crosses(state, moved, new, a, position, removed) -> bool:
    """The crossing check searched the plain way: the corners of every live face
    gathered, the near ones and the fan renumbered locally."""
    from spacemesh.geometry.intersections import pairs_cross

    fan = state.positions[new]
    fan[new == a] = position
    lo, hi = fan.min(axis=(0, 1)) - state.eps, fan.max(axis=(0, 1)) + state.eps
    alive = np.flatnonzero(state.face_alive)
    corners = state.positions[state.triangles[alive]]
    near = (np.all(corners.max(axis=1) >= lo, axis=1)
            & np.all(corners.min(axis=1) <= hi, axis=1))
    others = [int(f) for f in alive[near] if int(f) not in set(moved) | removed]
    k = len(moved)
    local = np.concatenate([new, state.triangles[others].reshape(-1, 3)])
    ids, inverse = np.unique(local, return_inverse=True)
    local_positions = state.positions[ids]
    local_positions[ids == a] = position
    local_tri = inverse.reshape(-1, 3)
    i_fan, j_fan = np.triu_indices(k, 1)
    i = np.concatenate([i_fan, np.repeat(np.arange(k), len(others))])
    j = np.concatenate([j_fan, k + np.tile(np.arange(len(others)), k)])
    box = local_positions[local_tri]
    low, high = box.min(axis=1) - state.eps, box.max(axis=1) + state.eps
    overlap = np.all((high[i] >= low[j]) & (high[j] >= low[i]), axis=1)
    i, j = i[overlap], j[overlap]
    return len(i) > 0 and bool(pairs_cross(local_positions, local_tri, i, j).any())


@pytest.mark.parametrize("seed", [0])  # one noisy ellipsoid: ~3 s, 523 checks
def test_the_crossing_check_answers_as_the_plain_search_does(monkeypatch, seed):
    """Every crossing check of both modes (kept face boxes, no local renumbering) gives
    the plain search's answer, and the kept boxes are the live faces' boxes."""
    from spacemesh.geometry.simplify import _Collapser

    fast = _Collapser._crosses
    answers: list[bool] = []

    def both(self, moved, new, a, position, removed):
        answer = fast(self, moved, new, a, position, removed)
        assert answer == _reference_crosses(self, moved, new, a, position, removed)
        alive = self.face_alive
        corners = self.positions[self.triangles[alive]]
        assert np.array_equal(self.box_low[alive], corners.min(axis=1))
        assert np.array_equal(self.box_high[alive], corners.max(axis=1))
        answers.append(answer)
        return answer

    monkeypatch.setattr(_Collapser, "_crosses", both)
    mesh = _noisy_ellipsoid(seed)
    points, _ = _points(mesh, 2000, seed)
    simplify(mesh, points, target_vertices=30)
    simplify(mesh, None, max_error=1e-3)
    assert sum(answers) > 50 and len(answers) - sum(answers) > 50  # both answers tested


def _reference_pairs_intersect(ta, tb, eps):
    """triangle_pairs_intersect the plain way: every test on every pair, then chosen."""
    from spacemesh.geometry.intersections import (
        COPLANAR_TOLERANCE,
        _coplanar_overlap,
        _segments_hit,
        _unit_normals,
    )

    na, good_a = _unit_normals(ta)
    nb, good_b = _unit_normals(tb)
    da = np.einsum("mkd,md->mk", tb - ta[:, None, 0], na)
    db = np.einsum("mkd,md->mk", ta - tb[:, None, 0], nb)
    apart = (np.all(da > eps, axis=1) | np.all(da < -eps, axis=1)
             | np.all(db > eps, axis=1) | np.all(db < -eps, axis=1))
    size = np.maximum(np.ptp(ta, axis=1).max(axis=1), np.ptp(tb, axis=1).max(axis=1))
    flat = np.maximum(eps, COPLANAR_TOLERANCE * size)[:, None]
    coplanar = np.all(np.abs(da) <= flat, axis=1) & np.all(np.abs(db) <= flat, axis=1)
    crossing = np.zeros(len(ta), dtype=bool)
    for s, t, normal in ((ta, tb, nb), (tb, ta, na)):
        for k in range(3):
            crossing |= _segments_hit(s[:, k], s[:, (k + 1) % 3], t, normal, eps)
    out = np.where(coplanar, _coplanar_overlap(ta, tb, na, flat[:, 0]), crossing)
    return out & ~apart & good_a & good_b


def test_the_pairs_test_answers_as_every_test_on_every_pair_does():
    """triangle_pairs_intersect tests each pair only where still open: the same answers
    as every test on every pair, on random pairs of every kind (apart, crossing,
    coplanar, sharing a corner, degenerate) and every batch size."""
    from spacemesh.geometry.intersections import triangle_pairs_intersect

    rng = np.random.default_rng(0)
    kinds = np.zeros(3, dtype=int)
    for count in (1, 2, 5, 40, 300):
        ta = rng.normal(size=(count, 3, 3))
        tb = ta + rng.normal(size=(count, 3, 3)) * rng.choice([1e-3, 0.3, 1.0], (count, 1, 1))
        flat = rng.random(count) < 0.3
        ta[flat, :, 2], tb[flat, :, 2] = 0.0, 0.0  # coplanar pairs
        shared = rng.random(count) < 0.3
        tb[shared, 0] = ta[shared, 0]  # sharing a corner
        degenerate = rng.random(count) < 0.05
        tb[degenerate, 2] = tb[degenerate, 1]
        ours = triangle_pairs_intersect(ta, tb, 1e-9)
        assert np.array_equal(ours, _reference_pairs_intersect(ta, tb, 1e-9))
        kinds += [ours.sum(), (~ours).sum(), (ours & flat).sum()]
    assert np.all(kinds > 5)


def _reference_candidates(quadric, a, b):
    """One edge's candidate costs and positions, as the collapses first made them."""
    from spacemesh.geometry.simplify import WELL_POSED

    middle = 0.5 * (a + b)
    candidates = [a, b, middle]
    block = quadric[:3, :3]
    scale = float(block[0, 0] + block[1, 1] + block[2, 2])
    if scale > 0 and abs(float(np.linalg.det(block))) > WELL_POSED * scale**3:
        optimum = np.linalg.solve(block, -quadric[:3, 3])
        if float(np.sum((optimum - middle) ** 2)) <= float(np.sum((a - b) ** 2)):
            candidates.append(optimum)
    h = np.ones((len(candidates), 4))
    h[:, :3] = candidates
    return np.einsum("ci,ij,cj->c", h, quadric, h), h


def test_the_edges_candidates_made_together_are_each_edges_own():
    """_edge_candidates makes the 3x3 solves of many edges at once: byte for byte each
    edge's own candidates, for well-posed quadrics (optimum near or far) and ill-posed
    ones (a flat region's planes, none)."""
    from spacemesh.geometry.simplify import _edge_candidates

    rng = np.random.default_rng(0)
    count = 400
    planes = rng.normal(size=(count, 6, 4))
    planes[: count // 4, :, :3] = [0.0, 0.0, 1.0]  # one plane's normal: ill posed
    quadrics = np.einsum("epi,epj->eij", planes, planes)
    quadrics[-10:] = 0.0
    a = rng.normal(size=(count, 3))
    b = a + rng.normal(size=(count, 3)) * rng.choice([1e-2, 1.0, 10.0], (count, 1))
    together = _edge_candidates(quadrics, a, b)
    sizes = set()
    for e, (costs, h) in enumerate(together):
        own_costs, own_h = _reference_candidates(quadrics[e].copy(), a[e], b[e])
        assert costs.tobytes() == own_costs.tobytes() and h.tobytes() == own_h.tobytes()
        sizes.add(len(h))
    assert sizes == {3, 4}
