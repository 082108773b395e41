"""The decoded mesh refined: removed vertices put back, diagonals flipped
(:mod:`spacemesh.decode.refinement`, ``DecodeOptions.reinsert``, ``flip``,
``flat_delaunay_degrees``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from spacemesh.connectivity import Connectivity
from spacemesh.decode import DecodeOptions, decode, refinement
from spacemesh.decode.refinement import flip_diagonals, reinsert_vertices
from spacemesh.encode import encode_connectivity
from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.connectivity import edge_f1_score, next_accuracy
from spacemesh.primitives import bounding_spheres, edge_keys
from spacemesh.spacetime import distance_operands
from spacemesh.topology import check_topology


def _operands(points: np.ndarray):
    return distance_operands(points, "euclidean", None)


def _valid(connectivity: Connectivity, positions: np.ndarray) -> bool:
    mesh, _ = connectivity.to_mesh(positions).remove_unreferenced_vertices()
    return check_topology(mesh).is_closed_oriented_manifold


def _edges(connectivity: Connectivity) -> set[tuple[int, int]]:
    return {tuple(e) for e in connectivity.edges.tolist()}


def _rhombus_slab() -> PolygonMesh:
    """A closed slab over a flat rhombus whose top and bottom are split along the long
    (not locally Delaunay) diagonal ``0-1`` (top) and ``4-5`` (bottom)."""
    top = [[-1.0, 0.0], [1.0, 0.0], [0.0, 0.3], [0.0, -0.3]]
    vertices = np.array([[x, y, z] for z in (0.5, -0.5) for x, y in top])
    faces = [(0, 3, 1), (0, 1, 2), (4, 6, 5), (4, 5, 7)]
    for a, b in ((0, 3), (3, 1), (1, 2), (2, 0)):  # top edges, counter-clockwise
        faces += [(b, a, a + 4), (b, a + 4, b + 4)]
    return PolygonMesh.from_faces(vertices, np.array(faces))


def test_flat_quads_get_their_delaunay_diagonal_whatever_the_scores():
    slab = _rhombus_slab()
    assert check_topology(slab).is_closed_oriented_manifold
    connectivity = encode_connectivity(slab)
    x = slab.vertices.copy()
    x[[0, 1, 4, 5]] *= 0.01  # the network "prefers" the long diagonals
    flipped, count = flip_diagonals(connectivity, _operands(x), slab.vertices,
                                    flat_degrees=1.0, by_score=False)
    assert count == 2
    assert {(2, 3), (6, 7)} <= _edges(flipped)
    assert not {(0, 1), (4, 5)} & _edges(flipped)
    assert _valid(flipped, slab.vertices)
    # with score flips too, the flat quads still take the Delaunay diagonal (the scores
    # may then flip the rims, which are not flat)
    both, _ = flip_diagonals(connectivity, _operands(x), slab.vertices, flat_degrees=1.0)
    assert {(2, 3), (6, 7)} <= _edges(both)
    assert _valid(both, slab.vertices)
    # without the flat rule, the scores keep the long diagonals
    kept, _ = flip_diagonals(connectivity, _operands(x), slab.vertices, by_score=True)
    assert {(0, 1), (4, 5)} <= _edges(kept)
    assert not {(2, 3), (6, 7)} & _edges(kept)


def test_score_flips_follow_the_embedding_and_stay_manifold():
    sphere = icosphere(1)
    connectivity = encode_connectivity(sphere)
    # embeddings = positions: every edge is shorter than the other diagonal of its quad
    same, count = flip_diagonals(connectivity, _operands(sphere.vertices), sphere.vertices,
                                 flat_degrees=1.0)
    assert count == 0 and same is connectivity
    # pull the two far corners of one quad together: that diagonal wins
    a, b = connectivity.edges[0]
    faces = [f.tolist() for f in sphere.faces if a in f and b in f]
    c, d = ({v for f in faces for v in f} - {a, b})
    x = sphere.vertices.copy()
    x[[c, d]] = 0.5 * (x[c] + x[d])
    flipped, count = flip_diagonals(connectivity, _operands(x), sphere.vertices)
    assert count >= 1
    assert (min(c, d), max(c, d)) in _edges(flipped)
    assert (min(a, b), max(a, b)) not in _edges(flipped)
    assert _valid(flipped, sphere.vertices)


def _without_vertex(mesh: PolygonMesh, v: int) -> Connectivity:
    """``mesh``'s connectivity with vertex ``v`` cut out and its hole fanned."""
    ring = encode_connectivity(mesh)
    start, stop = ring.offsets[v], ring.offsets[v + 1]
    # the link of v in the order of its faces: next around v
    neighbours = ring.neighbours[start:stop].tolist()
    order = [neighbours[0]]
    successor = ring.successor[start:stop] - start
    slot = 0
    for _ in range(len(neighbours) - 1):
        slot = int(successor[slot])
        order.append(neighbours[slot])
    kept = [f.tolist() for f in mesh.faces if v not in f]
    link = order[::-1] if any(
        (order[i], order[(i + 1) % len(order)]) in {(f[k], f[(k + 1) % 3]) for f in kept
                                                     for k in range(3)}
        for i in range(len(order))) else order
    fan = [(link[0], link[i], link[i + 1]) for i in range(1, len(link) - 1)]
    faces = np.array(kept + fan)
    return encode_connectivity(PolygonMesh.from_faces(mesh.vertices, faces), check=False)


def test_a_removed_vertex_goes_back_and_the_flips_restore_its_fan():
    sphere = icosphere(0)  # the icosahedron: every vertex has five neighbours
    holed = _without_vertex(sphere, 0)
    assert holed.degree[0] == 0 and _valid(holed, sphere.vertices)
    operands = _operands(sphere.vertices)
    back, inserted = reinsert_vertices(holed, np.array([0]), operands)
    assert inserted == 1 and back.degree[0] == 3
    assert _valid(back, sphere.vertices)
    restored, flips = flip_diagonals(back, operands, sphere.vertices, flat_degrees=1.0)
    assert flips == 2
    assert restored.to_mesh(sphere.vertices).face_key_set() == sphere.face_key_set()
    none, count = reinsert_vertices(restored, np.zeros(0, np.int64), operands)
    assert count == 0 and none is restored


def _noisy(emb):
    """``emb`` with Gaussian noise of 0.3 times its mean magnitude on the adjacency."""
    rng = np.random.default_rng(0)
    scale = np.abs(emb.adjacency).mean()
    return replace(emb, adjacency=emb.adjacency + 0.3 * scale * rng.normal(
        size=emb.adjacency.shape))


def test_refinement_brings_a_noisy_decode_closer_to_the_truth(fitted):
    mesh, emb = fitted
    truth = encode_connectivity(mesh)
    noisy = _noisy(emb)
    plain = DecodeOptions(max_sides=3)
    refined = replace(plain, reinsert=True, flip=True, flat_delaunay_degrees=1.0)
    before = decode(mesh.vertices, noisy, plain)
    after = decode(mesh.vertices, noisy, refined)
    assert check_topology(after.mesh).is_closed_oriented_manifold
    assert after.n_flipped + after.n_reinserted > 0
    n = mesh.n_vertices
    assert after.mesh.n_vertices >= before.mesh.n_vertices
    assert edge_f1_score(after.connectivity.edges, truth.edges, n) > edge_f1_score(
        before.connectivity.edges, truth.edges, n)
    assert next_accuracy(after.connectivity, truth) > next_accuracy(before.connectivity, truth)


def test_edge_keys_of_flipped_mesh_are_unique(fitted):
    mesh, emb = fitted
    result = decode(mesh.vertices, emb, DecodeOptions(max_sides=3, reinsert=True, flip=True,
                                                      flat_delaunay_degrees=1.0))
    keys = edge_keys(result.connectivity.edges, mesh.n_vertices)
    assert len(np.unique(keys)) == len(keys)
    # an exact fit stays exact
    assert result.mesh.face_key_set() == mesh.face_key_set()
    assert result.n_flipped == 0 and result.n_reinserted == 0


def _flipped_edges(mesh: PolygonMesh, count: int) -> tuple[Connectivity, list[tuple[int, int]]]:
    """``mesh``'s connectivity with ``count`` edges (in quads that share no triangle)
    turned to their other diagonal, and those edges."""
    faces = [list(map(int, f)) for f in mesh.faces]
    used: set[int] = set()
    turned = []
    for a, b in encode_connectivity(mesh).edges.tolist():
        pair = [i for i, f in enumerate(faces) if a in f and b in f]
        if len(turned) == count or set(pair) & used:
            continue
        t1, t2 = pair
        f1 = faces[t1]
        if (f1.index(b) - f1.index(a)) % 3 != 1:  # t1 holds a -> b
            t1, t2 = t2, t1
        (c,) = set(faces[t1]) - {a, b}
        (d,) = set(faces[t2]) - {a, b}
        faces[t1], faces[t2] = [d, b, c], [c, a, d]
        used |= {t1, t2}
        turned.append((a, b))
    wrong = encode_connectivity(PolygonMesh.from_faces(mesh.vertices, np.array(faces)))
    return wrong, turned


def _surface_points(mesh: PolygonMesh, count: int = 2000) -> np.ndarray:
    from spacemesh.primitives import sample_surface

    points, _ = sample_surface(mesh, count, np.random.default_rng(4))
    return points.astype(np.float64)


def test_fit_flips_turn_wrong_diagonals_to_the_points():
    sphere = icosphere(1)  # no flat quads: the vertices alone do not say which diagonal
    wrong, turned = _flipped_edges(sphere, 6)
    assert len(turned) == 6 and _valid(wrong, sphere.vertices)
    assert not {tuple(sorted(e)) for e in turned} & _edges(wrong)
    operands = _operands(sphere.vertices)
    points = _surface_points(sphere)
    fixed, count = flip_diagonals(wrong, operands, sphere.vertices, by_score=False,
                                  points=points, fit_gain=0.5)
    assert count == 6
    assert fixed.to_mesh(sphere.vertices).face_key_set() == sphere.face_key_set()
    # no (finite) points, or no gain: no fit flips
    for kwargs in ({"points": None, "fit_gain": 0.5}, {"points": points, "fit_gain": None},
                   {"points": points[:0], "fit_gain": 0.5},
                   {"points": np.full((4, 3), np.nan), "fit_gain": 0.5}):
        same, none = flip_diagonals(wrong, operands, sphere.vertices, by_score=False, **kwargs)
        assert none == 0 and same is wrong
    # points only at the vertices: both diagonals pass through them, nothing to gain
    far = flip_diagonals(wrong, operands, sphere.vertices, by_score=False,
                         points=wrong.to_mesh(sphere.vertices).vertices, fit_gain=0.5)
    assert far[1] == 0


def test_fit_and_score_flips_leave_each_others_diagonals():
    sphere = icosphere(1)
    points = _surface_points(sphere)
    # the fit turns six wrong diagonals right, though the network prefers the wrong
    # ones: the score does not turn them back (no cycle between the two)
    wrong, turned = _flipped_edges(sphere, 6)
    x = sphere.vertices.copy()
    wrong_pairs = set()
    for a, b in turned:
        faces = [f for f in np.asarray(sphere.faces).tolist() if a in f and b in f]
        c, d = sorted({v for f in faces for v in f} - {a, b})
        x[[c, d]] = x[[c, d]] + 0.45 * (x[[d, c]] - x[[c, d]])  # the wrong pair "closer"
        wrong_pairs.add((c, d))
    true_pairs = {tuple(sorted(e)) for e in turned}
    assert wrong_pairs <= _edges(wrong)
    fixed, _ = flip_diagonals(wrong, _operands(x), sphere.vertices, points=points,
                              fit_gain=0.5)
    assert true_pairs <= _edges(fixed) and not wrong_pairs & _edges(fixed)
    assert _valid(fixed, sphere.vertices)
    # without the points the network's preference wins
    kept, _ = flip_diagonals(wrong, _operands(x), sphere.vertices)
    assert wrong_pairs <= _edges(kept)
    # a score flip the points disagree with is not turned back by the fit either
    connectivity = encode_connectivity(sphere)
    a, b = connectivity.edges[0]
    faces = [f.tolist() for f in sphere.faces if a in f and b in f]
    c, d = ({v for f in faces for v in f} - {a, b})
    x = sphere.vertices.copy()
    x[[c, d]] = 0.5 * (x[c] + x[d])  # the network "prefers" c d
    with_points, count = flip_diagonals(connectivity, _operands(x), sphere.vertices,
                                        points=points, fit_gain=0.5)
    without, count_without = flip_diagonals(connectivity, _operands(x), sphere.vertices)
    assert count == count_without >= 1 and (min(c, d), max(c, d)) in _edges(with_points)
    assert _edges(with_points) == _edges(without)


def test_the_points_bring_a_noisy_decode_closer_to_the_truth(fitted):
    mesh, emb = fitted
    truth = encode_connectivity(mesh)
    noisy = _noisy(emb)
    refined = DecodeOptions(max_sides=3, reinsert=True, flip=True, flat_delaunay_degrees=1.0)
    points = _surface_points(mesh)
    without = decode(mesh.vertices, noisy, replace(refined, fit_gain=0.5))  # no points
    plain = decode(mesh.vertices, noisy, refined, points=points)  # no gain
    fitted_ = decode(mesh.vertices, noisy, replace(refined, fit_gain=0.5), points=points)
    assert without.mesh.face_key_set() == plain.mesh.face_key_set()
    assert check_topology(fitted_.mesh).is_closed_oriented_manifold
    n = mesh.n_vertices
    f1 = [edge_f1_score(r.connectivity.edges, truth.edges, n) for r in (plain, fitted_)]
    nxt = [next_accuracy(r.connectivity, truth) for r in (plain, fitted_)]
    assert f1[1] > f1[0] and nxt[1] > nxt[0]


def test_noisy_points_do_not_turn_right_diagonals(monkeypatch):
    sphere = icosphere(1)
    connectivity = encode_connectivity(sphere)
    points = _surface_points(sphere, 300)  # under four per triangle
    noisy = points + 0.05 * np.random.default_rng(5).normal(size=points.shape)
    operands = _operands(sphere.vertices)
    same, count = flip_diagonals(connectivity, operands, sphere.vertices, by_score=False,
                                 points=noisy, fit_gain=0.5)
    assert count == 0 and same is connectivity
    # the relative test alone is fooled by the few noisy points of some quads
    monkeypatch.setattr(refinement, "FIT_SIGNIFICANCE", 0.0)
    _, count = flip_diagonals(connectivity, operands, sphere.vertices, by_score=False,
                              points=noisy, fit_gain=0.5)
    assert count > 0
    monkeypatch.undo()
    # and noise of a tenth of that still lets the points fix wrong diagonals
    wrong, _ = _flipped_edges(sphere, 6)
    fixed, count = flip_diagonals(wrong, operands, sphere.vertices, by_score=False,
                                  points=points + 0.005 * np.random.default_rng(6).normal(
                                      size=points.shape), fit_gain=0.5)
    assert count == 6
    assert fixed.to_mesh(sphere.vertices).face_key_set() == sphere.face_key_set()


def test_every_triangle_a_point_lies_over_is_within_the_spheres_reach():
    """Reinsertion measures only the triangles whose bounding sphere, grown by
    OVER_REACH, holds the vertex: that must keep every triangle it lies over, whatever
    the triangle's shape (slivers, needles, near-degenerate ones)."""
    rng = np.random.default_rng(11)
    corners = rng.normal(size=(4000, 3, 3)) * rng.uniform(0.01, 1.0, (4000, 1, 3))
    corners[:500, 2] = corners[:500, 0] + 1e-3 * (corners[:500, 1] - corners[:500, 0])
    spheres = bounding_spheres(corners)
    over_any = 0
    for point in rng.normal(size=(60, 3)) * 0.7:
        over = np.flatnonzero(refinement.over_triangles(point, corners))
        reach = refinement._within_reach(point, *spheres)
        assert set(over.tolist()) <= set(reach.tolist())
        over_any += len(over)
    assert over_any > 100  # the points do lie over many triangles
    # the farthest points that still lie over a triangle: two barycentric coordinates at
    # the margin, the height at its limit (half the longest side) above the plane
    some = corners[500:1500]  # (1000, 3, 3), none degenerate
    a, b, c = some[:, 0], some[:, 1], some[:, 2]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    side = np.linalg.norm(some - np.roll(some, 1, axis=1), axis=2).max(axis=1)
    for weights in ([-0.099, -0.099, 1.198], [1.198, -0.099, -0.099], [-0.099, 1.198, -0.099]):
        w = np.asarray(weights)
        points = w[0] * a + w[1] * b + w[2] * c + 0.499 * side[:, None] * normal
        for row, point in enumerate(points):
            if refinement.over_triangles(point, corners[500 + row][None])[0]:
                assert 500 + row in refinement._within_reach(point, *spheres)
