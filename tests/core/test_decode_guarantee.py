"""Property tests: ANY embedding decodes to a valid oriented manifold polygon mesh."""

from dataclasses import replace

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from spacemesh.decode import DecodeOptions, Embeddings, decode
from spacemesh.geometry import GeometryOptions, refine_geometry
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.halfedge import HalfedgeMesh
from spacemesh.spacetime import pairwise_distance
from spacemesh.topology import check_topology


def assert_valid(result, n_input: int) -> None:
    halfedges = HalfedgeMesh.from_connectivity(result.connectivity)
    assert halfedges.problems() == []
    mesh = result.mesh
    assert len(result.vertex_ids) == mesh.n_vertices
    assert np.all(result.vertex_ids < n_input)
    if mesh.n_faces:
        report = check_topology(mesh)
        assert report.is_closed_oriented_manifold, report.defects()
        assert report.n_unreferenced_vertices == 0
        assert mesh.face_sizes.min() >= 3
    else:
        assert mesh.n_vertices == 0


@st.composite
def embeddings(draw):
    n = draw(st.integers(0, 60))
    k = draw(st.sampled_from([2, 4, 8, 16]))
    kp = draw(st.integers(1, 8))
    seed = draw(st.integers(0, 2**32 - 1))
    scale = draw(st.sampled_from([1e-3, 0.1, 1.0, 10.0]))
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, k)) * scale
    distance = draw(st.sampled_from(["spacetime", "euclidean", "dot"]))
    if n >= 2:  # a threshold that gives a sparse-to-moderate graph, or an extreme one
        d = pairwise_distance(x, distance=distance)[np.triu_indices(n, 1)]
        q = draw(st.sampled_from([0.0, 0.02, 0.08, 0.2, 0.5, 1.0]))
        tau = float(np.quantile(d, q)) + draw(st.sampled_from([-1e-9, 0.0, 1e-9]))
    else:
        tau = draw(st.floats(-10, 10))
    root, prev, nxt = (rng.normal(size=(n, kp)) * scale for _ in range(3))
    if n and draw(st.booleans()):  # sprinkle non-finite values
        bad = rng.random((n, k)) < 0.05
        x[bad] = rng.choice([np.nan, np.inf, -np.inf], size=bad.sum())
        root[rng.random((n, kp)) < 0.05] = np.nan
    emb = Embeddings(x, tau, root, prev, nxt)
    alive = rng.random(n) < 0.9 if draw(st.booleans()) else None
    # positions for the angular fallback: generic, all coincident, or partly non-finite
    positions = rng.normal(size=(n, 3))
    kind = draw(st.sampled_from(["generic", "coincident", "non-finite"]))
    if kind == "coincident":
        positions[:] = 0.5
    elif kind == "non-finite" and n:
        positions[rng.random(n) < 0.2] = np.nan
    fallback = draw(st.sampled_from(["angular", "greedy"]))
    unpinch = draw(st.sampled_from(["edge", "vertex"]))
    uncross = draw(st.booleans())
    max_sides = draw(st.sampled_from([None, 3, 4]))
    options = DecodeOptions(distance=distance, fallback=fallback, unpinch=unpinch,
                            uncross=uncross, max_sides=max_sides, reinsert=draw(st.booleans()),
                            flip=draw(st.booleans()),
                            flat_delaunay_degrees=draw(st.sampled_from([None, 1.0, 30.0])),
                            fit_gain=draw(st.sampled_from([None, 0.0, 0.5])))
    # conditioning points for the fit flips: none, on the vertices' scale, or partly
    # non-finite
    points = draw(st.sampled_from(["none", "cloud", "non-finite"]))
    cloud = None if points == "none" else rng.normal(size=(draw(st.integers(0, 80)), 3))
    if points == "non-finite" and len(cloud):
        cloud[rng.random(len(cloud)) < 0.2] = np.inf
    return emb, options, alive, positions, cloud


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(embeddings())
def test_any_embedding_decodes_to_valid_mesh(case):
    emb, options, alive, positions, points = case
    result = decode(positions, emb, options, alive, points=points)
    assert_valid(result, emb.n_vertices)
    if alive is not None:
        assert alive[result.vertex_ids].all()
    if options.reinsert:
        # putting removed vertices back only ever adds vertices to the same decode
        without = decode(positions, emb, replace(options, reinsert=False, flip=False,
                                                 fit_gain=None), alive)
        assert result.mesh.n_vertices >= without.mesh.n_vertices
        assert result.mesh.n_vertices == without.mesh.n_vertices + result.n_reinserted
    if options.max_sides is not None:
        # a longer face is left only when every one of its diagonals is an edge already
        edges = {tuple(e) for e in result.connectivity.edges.tolist()}
        indices, offsets = result.connectivity.faces()
        for f in range(len(offsets) - 1):
            face = indices[offsets[f] : offsets[f + 1]].tolist()
            m = len(face)
            if m > options.max_sides:
                diagonals = [(min(face[i], face[j]), max(face[i], face[j]))
                             for i in range(m) for j in range(i + 2, m) if (i, j) != (0, m - 1)]
                assert all(d in edges for d in diagonals)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(embeddings(), st.sampled_from([None, 10, 80]), st.booleans(), st.booleans())
def test_the_geometry_stage_keeps_the_guarantee(case, target, flips, guard):
    """Splits, fit and flips of any decode stay a closed oriented manifold; with the
    guard, the share of self-intersecting faces never grows."""
    emb, options, alive, positions, points = case
    decoded = decode(positions, emb, options, alive, points=points)
    cloud = points if points is not None else np.zeros((0, 3))
    refined = refine_geometry(decoded.mesh, cloud, None,
                              GeometryOptions(flips=flips, guard=guard, rounds=2),
                              target_vertices=target)
    mesh = refined.mesh
    assert mesh.n_vertices >= decoded.mesh.n_vertices
    if mesh.n_faces:
        assert check_topology(mesh).is_closed_oriented_manifold
        assert np.isfinite(mesh.vertices).all() or not refined.stats["kept"]
    if guard and decoded.mesh.n_faces > 1 and np.isfinite(decoded.mesh.vertices).all():
        before = self_intersecting_faces(decoded.mesh).mean()
        assert self_intersecting_faces(mesh).mean() <= before + 1e-12 or refined.stats[
            "n_split"] > 0


def test_splits_leave_a_two_triangle_pillow_alone():
    from spacemesh.geometry.stage import split_longest_edges
    from spacemesh.mesh import PolygonMesh

    positions = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    pillow = np.array([[0, 1, 2], [0, 2, 1]])
    moved, triangles = split_longest_edges(positions, pillow, 10)
    mesh = PolygonMesh(moved, triangles.reshape(-1), np.arange(0, 3 * len(triangles) + 1, 3))
    assert check_topology(mesh).is_closed_oriented_manifold


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 40), st.floats(-5, 5), st.sampled_from(["product", "sum", "max"]))
def test_degenerate_embeddings(n, tau, reduction):
    """Identical embeddings: every pair is (or no pair is) an edge; ties everywhere."""
    emb = Embeddings(np.zeros((n, 8)), tau, np.ones((n, 3)), np.ones((n, 3)), np.ones((n, 3)))
    result = decode(np.zeros((n, 3)), emb, DecodeOptions(reduction=reduction))
    assert_valid(result, n)


def test_special_thresholds():
    rng = np.random.default_rng(5)
    for tau in [np.nan, np.inf, -np.inf, 1e300]:
        emb = Embeddings(
            rng.normal(size=(30, 8)), tau, *(rng.normal(size=(30, 4)) for _ in range(3))
        )
        assert_valid(decode(rng.normal(size=(30, 3)), emb), 30)


def test_large_random_input_is_bounded():
    """2,000 random vertices with a dense graph still decode (degree bound, fast rule)."""
    rng = np.random.default_rng(6)
    n = 2000
    emb = Embeddings(rng.normal(size=(n, 16)), 2.0, *(rng.normal(size=(n, 6)) for _ in range(3)))
    result = decode(rng.normal(size=(n, 3)), emb)
    assert_valid(result, n)
