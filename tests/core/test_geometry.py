"""spacemesh.geometry: farthest points, the vertex fit, sharp features, splits, the
self-intersection test and the fit report."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.geometry import (
    GeometryOptions,
    VertexFitOptions,
    farthest_point_sampling,
    fit_report,
    fit_score,
    fit_vertices,
    refine_geometry,
)
from spacemesh.geometry.fitting import barycentric, estimate_point_normals, fit_to_surface
from spacemesh.geometry.intersections import intersecting_triangles, self_intersecting_faces
from spacemesh.geometry.stage import split_longest_edges
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface
from spacemesh.topology import check_topology


def _triangles(mesh: PolygonMesh) -> np.ndarray:
    return mesh.face_indices.reshape(-1, 3)


def _mesh(positions, triangles) -> PolygonMesh:
    triangles = np.asarray(triangles).reshape(-1, 3)
    return PolygonMesh(np.asarray(positions, float), triangles.reshape(-1),
                       np.arange(0, 3 * len(triangles) + 1, 3))


def test_farthest_points_are_distinct_spread_and_seeded():
    points = np.random.default_rng(0).random((2000, 3))
    a = farthest_point_sampling(points, 100, seed=0)
    assert len(set(a.tolist())) == 100
    assert np.array_equal(a, farthest_point_sampling(points, 100, seed=0))
    assert not np.array_equal(a, farthest_point_sampling(points, 100, seed=1))
    random = np.random.default_rng(1).choice(2000, 100, replace=False)

    def gap(index):
        d = np.linalg.norm(points[index][:, None] - points[index][None], axis=2)
        return np.min(d + np.eye(len(index)) * 9)

    assert gap(a) > 2 * gap(random)  # spread: the closest pair is far apart
    assert len(farthest_point_sampling(points[:5], 100)) == 5
    assert len(farthest_point_sampling(points, 0)) == 0


def _plain_farthest_points(points, count, seed, weights=None):
    """The plain O(P count) loop: the oracle of the blocked sampling."""
    count = min(count, len(points))
    scale = np.ones(len(points)) if weights is None else np.asarray(weights, float) ** 2
    chosen = [int(np.random.default_rng(seed).integers(len(points)))]
    nearest = np.full(len(points), np.inf)
    for _ in range(1, count):
        gap = points - points[chosen[-1]]
        np.minimum(nearest, np.einsum("pd,pd->p", gap, gap) * scale, out=nearest)
        nearest[chosen[-1]] = -1.0
        chosen.append(int(np.argmax(nearest)))
    return np.array(chosen[:count], dtype=np.int64)


def test_blocked_farthest_points_are_the_plain_loops():
    """The blocks only skip work: the same indices as the plain loop for every block
    size, with weights, duplicates, exact ties (a grid), flat and tiny clouds."""
    rng = np.random.default_rng(3)
    grid = torus_grid(12, 6).vertices
    clouds = {"random": rng.random((600, 3)), "one": rng.random((1, 3)),
              "duplicates": np.concatenate([grid, grid, grid[:20]]),
              "flat": np.c_[rng.random((400, 2)), np.zeros(400)],
              "lattice": rng.integers(0, 4, (300, 3)).astype(float)}
    for name, points in clouds.items():
        boosted = 1 + 2.0 * (rng.random(len(points)) < 0.2)
        for seed, weights in [(0, None), (1, boosted), (2, rng.random(len(points)))]:
            for count in (1, 9, len(points) // 3, len(points)):
                want = _plain_farthest_points(points, count, seed, weights)
                for block in (1, 7, 256):
                    got = farthest_point_sampling(points, count, seed=seed,
                                                  weights=weights, block=block)
                    assert np.array_equal(got, want), (name, seed, count, block)


def test_barycentric_coordinates_rebuild_the_point():
    rng = np.random.default_rng(2)
    corners = rng.normal(size=(50, 3, 3))
    weights = rng.dirichlet([1, 1, 1], size=50)
    points = np.einsum("mk,mkd->md", weights, corners)
    assert np.allclose(barycentric(points, corners), weights, atol=1e-9)


def test_the_fit_brings_a_shrunk_sphere_back_to_its_points():
    sphere = icosphere(2)
    unit = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    points, _ = sample_surface(sphere.with_vertices(unit), 3000, np.random.default_rng(0))
    moved, energies = fit_vertices(unit * 0.8, _triangles(sphere), points)
    radius = np.linalg.norm(moved, axis=1)
    assert np.abs(radius - 1).max() < 0.03 and np.abs(0.8 - 1) > 0.15
    assert energies[-1] < 0.05 * energies[0]


def test_tangent_planes_put_vertices_on_the_corners():
    """A rounded cube's vertices near the corners go onto the corners when the
    tangent-plane quadric is on, not without it."""
    cube = cube_quads(2.0).with_vertices(cube_quads(2.0).vertices - 1.0)
    points, normals = sample_surface(cube, 6000, np.random.default_rng(1))
    sphere = icosphere(3)
    start = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True) * 1.5
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)

    def corner_error(options):
        moved, _ = fit_vertices(start, _triangles(sphere), points, normals, options)
        gap = np.linalg.norm(moved[None] - corners[:, None], axis=2).min(axis=1)
        return gap.max()

    with_planes = corner_error(VertexFitOptions(iterations=12, plane_neighbours=24))
    without = corner_error(VertexFitOptions(iterations=12, plane_neighbours=24, plane_weight=0.0))
    assert with_planes < 0.6 * without


def test_flat_regions_stay_flat():
    """Points on a plane: vertices on it stay on it (the quadric holds the normal
    direction only), and move little within it."""
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 6), np.linspace(0, 1, 6)), -1).reshape(-1, 2)
    positions = np.c_[grid, np.zeros(len(grid))]
    triangles = [(i * 6 + j, i * 6 + j + 1, (i + 1) * 6 + j) for i in range(5) for j in range(5)]
    triangles += [(i * 6 + j + 1, (i + 1) * 6 + j + 1, (i + 1) * 6 + j)
                  for i in range(5) for j in range(5)]
    rng = np.random.default_rng(3)
    points = np.c_[rng.random((2000, 2)), np.zeros(2000)]
    moved, _ = fit_vertices(positions, np.asarray(triangles), points)
    assert np.abs(moved[:, 2]).max() < 1e-9
    assert np.linalg.norm(moved - positions, axis=1).max() < 0.1


def test_point_normals_are_the_planes_of_the_neighbourhoods():
    rng = np.random.default_rng(4)
    points = np.c_[rng.random((500, 2)), 0.3 * np.ones(500)]
    assert np.allclose(np.abs(estimate_point_normals(points)[:, 2]), 1.0)


def test_splits_reach_the_count_and_keep_the_manifold():
    sphere = icosphere(1)
    for target in (sphere.n_vertices, 50, 97, 300):
        positions, triangles = split_longest_edges(sphere.vertices, _triangles(sphere), target)
        mesh = _mesh(positions, triangles)
        assert mesh.n_vertices == max(target, sphere.n_vertices)
        assert check_topology(mesh).is_closed_oriented_manifold


def test_intersections_agree_with_pymeshlab_where_it_looks():
    """pymeshlab's per-face filter finds the crossings of non-coplanar triangles; ours
    finds the same faces there (and, beyond it, coplanar overlaps)."""
    pymeshlab = pytest.importorskip("pymeshlab")

    def pymeshlab_faces(mesh):
        meshset = pymeshlab.MeshSet()
        meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices,
                                        face_matrix=_triangles(mesh).astype(np.int32)))
        meshset.compute_selection_by_self_intersections_per_face()
        return meshset.current_mesh().face_selection_array()

    a, b = icosphere(2), icosphere(2)
    both = _mesh(np.concatenate([a.vertices, b.vertices + np.array([0.8, 0.1, 0.0])]),
                 np.concatenate([_triangles(a), _triangles(b) + a.n_vertices]))
    folded = a.with_vertices(a.vertices.copy())
    folded.vertices[0] *= -0.2  # a vertex pushed through the opposite side
    for mesh in (a, both, folded):
        assert np.array_equal(self_intersecting_faces(mesh), pymeshlab_faces(mesh)), mesh
    assert self_intersecting_faces(both).any() and not self_intersecting_faces(a).any()
    flat = _mesh([[0, 0, 0], [2, 0, 0], [0, 2, 0], [1.5, 1.5, 0]], [[0, 1, 2], [1, 0, 3]])
    assert self_intersecting_faces(flat).all()  # folded onto each other within the plane
    assert not pymeshlab_faces(flat).any()  # what pymeshlab's filter misses


def test_the_vectorised_pair_test_agrees_with_the_reference():
    from spacemesh.data.validate import triangles_intersect
    from spacemesh.geometry.intersections import triangle_pairs_intersect

    rng = np.random.default_rng(7)
    ta = rng.normal(size=(400, 3, 3))
    tb = ta + rng.normal(scale=0.7, size=(400, 3, 3))
    flat = rng.normal(size=(200, 3, 3))
    flat[..., 2] = 0.0  # coplanar pairs, overlapping or not
    ta = np.concatenate([ta, flat[:100]])
    tb = np.concatenate([tb, flat[100:] * 0.5])
    ours = triangle_pairs_intersect(ta, tb)
    reference = [triangles_intersect(a, b) for a, b in zip(ta, tb, strict=True)]
    assert ours.tolist() == reference
    assert 0.1 < ours.mean() < 0.9  # both answers are exercised


def test_a_pairs_verdict_does_not_depend_on_the_rest_of_the_mesh():
    """Two triangles 3e-9 apart (a standing one above a lying one) do not touch at their
    own size; a third triangle far away, which makes the mesh 100 times larger, does not
    make them touch (a repair's kept faces keep their verdict as its new faces come)."""
    from spacemesh.geometry.intersections import CrossingFaces, pairs_cross

    gap = 3e-9
    corners = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, gap], [0.5, 0.3, 1],
               [0.3, 0.5, 1]]
    pair = _mesh(corners, [[0, 1, 2], [3, 4, 5]])
    far = _mesh([*corners, [100, 0, 0], [101, 0, 0], [100, 1, 0]],
                [[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    assert not self_intersecting_faces(pair).any()
    assert not self_intersecting_faces(far).any()
    touching = _mesh([*corners[:3], [0.3, 0.3, 0.0], *corners[4:]], [[0, 1, 2], [3, 4, 5]])
    assert self_intersecting_faces(touching).all()  # and at 0 apart they do touch
    # the tracker agrees as the far triangle moves further away
    tracker = CrossingFaces(far)
    moved = far.vertices.copy()
    moved[6:] *= 10.0
    assert not tracker.move(moved).any()
    i, j = np.array([0]), np.array([1])
    triangles = pair.face_indices.reshape(-1, 3)
    assert not pairs_cross(pair.vertices, triangles, i, j)[0]


@pytest.mark.parametrize("whole_extent", [False, True])
def test_crossing_pairs_are_every_crossing_pair_however_uneven_the_triangles(whole_extent):
    """The candidate search finds each pair from its larger triangle within twice that
    triangle's radius: a jittered torus with a few long, thin triangles laid across it
    and a soup of triangles of every size gives exactly the crossing pairs of the test
    run on every pair, and so does the search restricted to some triangles (``among``:
    every pair with one of them)."""
    from spacemesh.geometry.intersections import crossing_pairs, pairs_cross, touching_eps

    rng = np.random.default_rng(5)
    torus = torus_grid(12, 8)
    positions = torus.vertices + rng.normal(scale=0.05, size=torus.vertices.shape)
    long_ones = [[0, 40, 81], [5, 60, 90], [17, 33, 71]]  # across the torus: long, thin
    # and a soup of triangles of every size that cross others anywhere, tip to tip too
    soup = rng.uniform(-1.5, 1.5, (60, 1, 3)) + rng.normal(size=(60, 3, 3)) * rng.uniform(
        0.05, 0.6, (60, 1, 1))
    positions = np.concatenate([positions, soup.reshape(-1, 3)])
    triangles = np.concatenate([_triangles(torus), long_ones,
                                torus.n_vertices + np.arange(180).reshape(60, 3)])
    i, j = np.triu_indices(len(triangles), 1)  # every pair
    floor = touching_eps(positions, triangles) if whole_extent else 0.0
    every = pairs_cross(positions, triangles, i, j, floor=floor)
    expected = set(zip(i[every].tolist(), j[every].tolist(), strict=True))
    assert len(expected) > 10  # the long triangles cross the tube
    found = crossing_pairs(positions, triangles, whole_extent=whole_extent)
    assert {tuple(p) for p in found.tolist()} == expected
    among = rng.choice(len(triangles), size=20, replace=False)
    some = crossing_pairs(positions, triangles, among=among, whole_extent=whole_extent)
    assert {tuple(p) for p in some.tolist()} == {
        (a, b) for a, b in expected if a in set(among.tolist()) or b in set(among.tolist())}


def test_near_contacts_are_read_at_the_whole_meshs_extent():
    """The seeds' check reads near contacts: the pair 3e-9 apart above does not touch at
    its own size, but does within 1e-9 of a mesh 100 times larger (its far triangle
    touches nothing); at 3e-7 apart no face is a near contact."""
    from spacemesh.geometry.intersections import near_contact_faces

    def mesh_at(gap: float) -> PolygonMesh:
        corners = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, gap], [0.5, 0.3, 1],
                   [0.3, 0.5, 1], [100, 0, 0], [101, 0, 0], [100, 1, 0]]
        return _mesh(corners, [[0, 1, 2], [3, 4, 5], [6, 7, 8]])

    assert not self_intersecting_faces(mesh_at(3e-9)).any()
    assert near_contact_faces(mesh_at(3e-9)).tolist() == [True, True, False]
    assert not near_contact_faces(mesh_at(3e-7)).any()
    assert not near_contact_faces(_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])).any()


def test_coplanar_neighbours_are_not_intersections():
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 5)), -1).reshape(-1, 2)
    positions = np.c_[grid, np.zeros(len(grid))]
    triangles = [(i * 5 + j, i * 5 + j + 1, (i + 1) * 5 + j) for i in range(4) for j in range(4)]
    triangles += [(i * 5 + j + 1, (i + 1) * 5 + j + 1, (i + 1) * 5 + j)
                  for i in range(4) for j in range(4)]
    assert not intersecting_triangles(positions, np.asarray(triangles)).any()
    crossing = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0],
                         [0.2, 0.2, -0.5], [0.3, 0.2, 0.5], [0.2, 0.3, 0.5]], float)
    assert intersecting_triangles(crossing, np.array([[0, 1, 2], [3, 4, 5]])).all()


def test_the_fit_report_measures_distances_coverage_and_components():
    sphere = icosphere(3)
    unit = sphere.with_vertices(sphere.vertices / np.linalg.norm(sphere.vertices, axis=1,
                                                                 keepdims=True))
    points, _ = sample_surface(unit, 3000, np.random.default_rng(5))
    good = fit_report(unit, points)
    assert good.points_to_mesh_mean < 0.01 and good.coverage > 0.95
    assert good.components == 1 and good.self_intersections == 0.0
    assert good.diagonal == pytest.approx(np.linalg.norm(np.ptp(points, axis=0)))
    small = fit_report(unit.with_vertices(unit.vertices * 0.8), points)
    assert small.points_to_mesh_mean == pytest.approx(0.2, abs=0.01)
    assert small.coverage < 0.05 and small.score > 10 * good.score
    assert small.points_to_mesh_mean_rel == pytest.approx(
        small.points_to_mesh_mean / small.diagonal)
    two = _mesh(np.concatenate([unit.vertices, unit.vertices + 5]),
                np.concatenate([_triangles(unit), _triangles(unit) + unit.n_vertices]))
    assert fit_report(two, points).components == 2
    assert (good.pieces, good.genus, good.boundary_loops) == (1, 0, 0)
    assert (fit_report(two, points).pieces, fit_report(two, points).genus) == (2, 0)
    empty = fit_report(PolygonMesh.empty(), points)
    assert np.isnan(empty.score) and empty.coverage == 0.0
    assert (empty.pieces, empty.genus, empty.boundary_loops) == (0, 0, 0)
    scaled = fit_report(unit.with_vertices(unit.vertices * 10), points * 10)
    assert scaled.mesh_to_points_mean_rel == pytest.approx(good.mesh_to_points_mean_rel,
                                                           rel=1e-6)


def test_fit_score_is_the_reports_score_without_the_rest():
    sphere = icosphere(2)
    points, _ = sample_surface(sphere, 25_000, np.random.default_rng(6))  # over the cap
    points[3] = np.nan  # a non-finite row is left out by both
    for mesh in (sphere, sphere.with_vertices(sphere.vertices * 0.7)):
        assert fit_score(mesh, points) == pytest.approx(fit_report(mesh, points).score,
                                                        rel=1e-12)
    assert fit_score(sphere, points) < fit_score(sphere.with_vertices(sphere.vertices * 0.7),
                                                 points)
    assert fit_score(PolygonMesh.empty(), points) == np.inf


def _coarse_ellipsoid(n_points: int, seed: int) -> tuple[PolygonMesh, np.ndarray]:
    """A 42-vertex sphere squashed toward a 2 x 1 x 1 ellipsoid, and ``(n_points, 3)``
    points sampled on that ellipsoid."""
    sphere = icosphere(1)
    unit = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    truth = icosphere(4)
    truth = truth.with_vertices(truth.vertices / np.linalg.norm(truth.vertices, axis=1,
                                                                keepdims=True) * [2, 1, 1])
    points, _ = sample_surface(truth, n_points, np.random.default_rng(seed))
    return sphere.with_vertices(unit * [1.6, 0.8, 0.8]), points


def test_the_stage_fits_a_coarse_decode_and_keeps_it_valid():
    coarse, points = _coarse_ellipsoid(4000, 6)
    result = refine_geometry(coarse, points, None, GeometryOptions(), target_vertices=120)
    assert result.mesh.n_vertices == 120 and result.stats["n_split"] == 120 - 42
    assert check_topology(result.mesh).is_closed_oriented_manifold
    assert fit_report(result.mesh, points).score < 0.5 * fit_report(coarse, points).score
    assert result.stats["intersections_after"] <= result.stats["intersections_before"]
    untouched = refine_geometry(coarse, np.full((10, 3), np.nan))
    assert untouched.mesh is coarse and not untouched.stats["kept"]


def test_a_far_target_is_split_in_fitted_steps():
    """Nine times the coarse mesh's vertices: split and fitted 42 -> 84 -> 168 -> 336 ->
    400, every split vertex ends on the surface (none left where its split put it)."""
    coarse, points = _coarse_ellipsoid(6000, 7)
    result = refine_geometry(coarse, points, None, GeometryOptions(), target_vertices=400)
    assert result.stats["split_steps"] == 4 and result.stats["n_split"] == 400 - 42
    assert result.mesh.n_vertices == 400 and result.stats["kept"]
    assert check_topology(result.mesh).is_closed_oriented_manifold
    ellipsoid = np.linalg.norm(result.mesh.vertices / [2, 1, 1], axis=1)  # 1 on the truth
    assert np.abs(ellipsoid - 1).max() < 0.02
    assert fit_report(result.mesh, points).score < 0.5 * fit_report(coarse, points).score
    one = refine_geometry(coarse, points, None, GeometryOptions(), target_vertices=80)
    assert "split_steps" not in one.stats and one.stats["n_split"] == 80 - 42


def test_a_triangle_with_a_corner_on_its_opposite_side_has_collapsed():
    """The guard's collapsed triangles: a split vertex moved back onto the edge that a flip
    made gives a triangle of zero area (the skull's remake at 5,154 vertices had six)."""
    from spacemesh.geometry.stage import _collapsed_count

    positions = np.array([[0.0, 0, 0], [2, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1e-5, 0]])
    assert _collapsed_count(positions, np.array([[0, 1, 2]])) == 1  # the midpoint
    assert _collapsed_count(positions, np.array([[0, 1, 3], [0, 1, 4]])) == 0


def test_noise_is_measured_and_smoothed():
    """point_noise reads the points' scatter about their planes; with noisy points the
    noise-following springs give a surface closer to the truth than the plain fit."""
    from spacemesh.geometry.fitting import point_noise

    rng = np.random.default_rng(8)
    plane = np.c_[rng.random((3000, 2)), np.zeros(3000)]
    assert point_noise(plane) < 1e-9
    noisy_plane = plane + rng.normal(scale=[0, 0, 0.01], size=plane.shape)
    assert 0.004 < point_noise(noisy_plane) < 0.012
    sphere = icosphere(3)
    unit = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    points, _ = sample_surface(sphere.with_vertices(unit), 3000, rng)
    points = points + rng.normal(scale=0.04, size=points.shape)

    def error(options):
        moved, _ = fit_vertices(unit, _triangles(sphere), points, None, options)
        return np.abs(np.linalg.norm(moved, axis=1) - 1).mean()

    springy, stiff = VertexFitOptions(noise_spring=5.0), VertexFitOptions(noise_spring=0.0)
    assert error(springy) < 0.8 * error(stiff)


def test_a_coarse_sphere_fitted_to_a_fine_one_lies_closer_than_one_laid_on_it():
    from spacemesh.primitives.closest import nearest_triangles

    coarse, fine = icosphere(1), icosphere(4)  # both with every vertex on the unit sphere
    triangles = coarse.face_indices.reshape(-1, 3)
    fine_triangles = fine.face_indices.reshape(-1, 3)
    samples, _ = sample_surface(fine, 4000, np.random.default_rng(0))
    moving = np.ones(coarse.n_vertices, dtype=bool)
    moving[:3] = False
    fitted = fit_to_surface(coarse.vertices, triangles, moving, fine.vertices, fine_triangles)
    before = float(nearest_triangles(samples, coarse.vertices, triangles)[1].mean())
    after = float(nearest_triangles(samples, fitted, triangles)[1].mean())
    assert after < 0.5 * before  # chords no longer all inside the sphere
    radius = np.linalg.norm(fitted[moving], axis=1)
    assert radius.min() > 1.0  # the fitted vertices stand off the surface, outwards
    np.testing.assert_array_equal(fitted[~moving], coarse.vertices[~moving])


def test_the_guard_scales_the_whole_fit_back_before_dropping_it():
    """When moving the crossing faces' corners back does not keep the share of crossing
    faces, the guard takes the largest fraction of every vertex's move that does
    (stage._scaled_back), and gives up only when none does."""
    from spacemesh.geometry.intersections import CrossingFaces
    from spacemesh.geometry.stage import GUARD_FRACTIONS, _intersection_share, _scaled_back

    a, b = icosphere(2), icosphere(2)
    tri = np.concatenate([_triangles(a), _triangles(b) + a.n_vertices])
    shift = np.array([2.0, 0.0, 0.0])
    apart = np.concatenate([a.vertices - shift, b.vertices + shift])
    mesh = _mesh(apart, tri)
    moved = apart.copy()
    moved[: a.n_vertices] += [2.5, 0, 0]  # the first sphere driven into the second
    assert _intersection_share(mesh, moved, tri, None)[0] > 0
    stats: dict = {}
    scaled = _scaled_back(CrossingFaces(mesh.with_vertices(moved)), moved, apart, None, 0.0,
                          stats)
    assert scaled is not None and stats["guard_fraction"] == GUARD_FRACTIONS[0]
    assert scaled[1] == 0.0
    assert np.allclose(scaled[0], apart + GUARD_FRACTIONS[0] * (moved - apart))
    # from spheres that already cross, no fraction has fewer crossing faces than none
    overlapping = apart.copy()
    overlapping[: a.n_vertices] += [3.5, 0, 0]
    nudged = overlapping + np.array([0.0, 0.01, 0.0])
    assert _scaled_back(CrossingFaces(mesh.with_vertices(nudged)), nudged, overlapping, None,
                        0.0, {}) is None


def test_the_corner_spread_is_numpys_peak_to_peak():
    from spacemesh.geometry.intersections import _spread

    corners = np.random.default_rng(5).normal(size=(50, 6, 3))
    assert np.array_equal(_spread(corners), np.ptp(corners, axis=1).max(axis=1))


@pytest.mark.parametrize("lift, crosses", [(1e-4, True), (1e-9, True), (0.01, False),
                                           (0.5, False)])
def test_a_fin_folded_within_a_hair_crosses(lift, crosses):
    from spacemesh.geometry.intersections import pairs_cross

    # two triangles on the edge 0-1, the second folded back over the first: the gap
    # between them is ``lift`` at its far corner (a fin within 0.1 degree of flat, which
    # slicers and PyMeshLab read as crossing), or a fold opened by 0.6 or 29 degrees
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, 0.9, lift],
                         [0.5, -1, 0]], dtype=np.float64)
    triangles = np.array([[0, 1, 2], [1, 0, 3], [1, 0, 4]])
    verdict = pairs_cross(vertices, triangles, np.array([0, 0]), np.array([1, 2]))
    assert verdict.tolist() == [crosses, False]  # a flat neighbour never crosses


def test_one_triangle_twice_crosses():
    from spacemesh.geometry.intersections import pairs_cross

    # a two-face pillow (the same corners, both orientations): the faces coincide
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    triangles = np.array([[0, 1, 2], [0, 2, 1]])
    assert pairs_cross(vertices, triangles, np.array([0]), np.array([1])).tolist() == [True]


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e3])
@pytest.mark.parametrize("rise, crosses", [(3e-5, True), (1e-7, True), (0.0, False),
                                           (-3e-5, False)])
def test_a_face_hinged_on_the_other_diagonal_of_a_quad_crosses_however_thin(scale, rise,
                                                                             crosses):
    from spacemesh.geometry.intersections import pairs_cross

    # the nut's one-sided output (docs/GEOMETRY.md, "One corner"): a nearly flat quad
    # 0-1-2-3 split on 0-2, and a face on the other diagonal 1-3 dropping away from it
    # (corner 4 below). Corner 3 rises by ``rise``: the face then dips under the quad's
    # first triangle by a sliver far thinner than the old shrink of 1e-3 of its size, and
    # meets the second along a ray from corner 3; lowered, it stays clear of both, and
    # flat, its side 1-3 only lies on them (a contact along a side, not a crossing)
    vertices = scale * np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, rise],
                                 [0.5, 0.5, -0.4]], dtype=np.float64)
    triangles = np.array([[0, 1, 2], [0, 2, 3], [1, 3, 4]])
    verdict = pairs_cross(vertices, triangles, np.array([0, 1, 0]), np.array([2, 2, 1]))
    assert verdict.tolist() == [crosses, crosses, False]


def test_one_corner_pairs_cross_only_where_a_ray_lies_in_both():
    from spacemesh.geometry.intersections import pairs_cross

    # triangles that share corner 0 only. Flat ones (z = 0) span an angle around it:
    # 0: 0-45 degrees, 1: 27-79, 2: 79-135, 3: 135-225, 6: 45-79 (its side 0-10 on
    # the side 0-3 of 2); 4 stands upright along the direction at 27 degrees, 5 along
    # the one at 79 degrees
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0.2, 1, 0], [1, 0.5, 0],
                         [-1, 1, 0], [-1, -1, 0], [1, 0.5, 1], [1, 0.5, -1],
                         [0, 1, 1], [0.1, 0.5, 0]], dtype=np.float64)
    triangles = np.array([[0, 1, 2], [0, 4, 3], [0, 3, 5], [0, 5, 6], [0, 7, 8],
                          [0, 3, 9], [0, 2, 10]])
    i = np.array([0, 0, 0, 0, 0, 2, 6])
    j = np.array([1, 2, 3, 4, 5, 4, 2])
    assert pairs_cross(vertices, triangles, i, j).tolist() == [
        True,  # flat, their angles overlap (a fan folded past 360 degrees)
        False,  # flat, apart
        False,  # flat, opposite
        True,  # upright, through the inside of 0 from the corner
        False,  # upright, standing outside 0
        False,  # upright, standing outside 2
        False,  # flat, their sides lie along each other on 0-10 (a polygon's corner on
        # its neighbour's straight side): they only touch there
    ]
