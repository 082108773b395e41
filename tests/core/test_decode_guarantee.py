"""Property tests: ANY embedding decodes to a valid oriented manifold polygon mesh.

Hypothesis draws the inputs themselves, not a seed, so it can search and shrink:
vertex positions (generic, snapped into coincident clusters, collinear, coplanar, all
coincident, partly NaN), adjacency embeddings (free, derived from the positions, with
duplicated rows), thresholds (quantiles of the drawn distances, or non-finite),
permutation embeddings (free, constant: ties everywhere) and every decode option. The
refinement's triangle operations (:func:`spacemesh.decode.refinement.flip_diagonals`)
get a property test of their own on drawn convex polyhedra, where hypothesis finds in a
few examples the quads whose flips would double an edge.

Besides the topology, each decode is checked geometrically: its vertices are the input
positions; a face of zero area only has corners whose input positions are coincident
or collinear; and the geometry stage's reported self-intersection shares are those that
:mod:`spacemesh.geometry.intersections` measures on the meshes it returns.

The runs are bounded and reproducible (``derandomize=True``, a fixed ``max_examples``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy.spatial import ConvexHull, QhullError

from spacemesh.decode import DecodeOptions, Embeddings, decode
from spacemesh.decode.refinement import flip_diagonals
from spacemesh.encode import connectivity_from_faces
from spacemesh.geometry import GeometryOptions, refine_geometry
from spacemesh.geometry.intersections import self_intersecting_faces, self_intersection_fraction
from spacemesh.halfedge import HalfedgeMesh
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import edge_keys
from spacemesh.spacetime import distance_operands, pairwise_distance
from spacemesh.topology import check_topology
from tests.validity import assert_valid_mesh

#: Bounded, reproducible runs: the same examples every time, seconds in all.
BOUNDED = settings(deadline=None, derandomize=True, database=None,
                   suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                          HealthCheck.filter_too_much])
#: Relative size below which an area or a distance counts as zero.
ZERO = 1e-9

COORDINATE = st.floats(-1, 1, allow_nan=False, width=32)
EMBEDDING = st.floats(-2, 2, allow_nan=False, width=32)
OFFSET = st.floats(-0.25, 0.25, allow_nan=False, width=32)


# ---------------------------------------------------------------------- geometry checks
def face_areas(mesh: PolygonMesh) -> np.ndarray:
    """Each face's vector area (Newell), as a length."""
    areas = np.zeros(mesh.n_faces)
    for f in range(mesh.n_faces):
        corners = mesh.vertices[mesh.face_indices[mesh.face_offsets[f]:
                                                  mesh.face_offsets[f + 1]]]
        areas[f] = 0.5 * np.linalg.norm(np.cross(corners, np.roll(corners, -1, 0)).sum(0))
    return areas


def degenerate_corners(corners: np.ndarray, scale: float) -> bool:
    """Two corners coincide or three are collinear (relative to ``scale``)."""
    m = len(corners)
    for i in range(m):
        for j in range(i + 1, m):
            u = corners[j] - corners[i]
            if np.linalg.norm(u) <= ZERO * scale:
                return True
            for k in range(j + 1, m):
                if np.linalg.norm(np.cross(u, corners[k] - corners[i])) <= ZERO * scale**2:
                    return True
    return False


def assert_geometry_explained(result, positions: np.ndarray) -> None:
    """The decode keeps the input positions, and a face of zero area only has corners
    whose input positions are degenerate."""
    mesh = result.mesh
    expected = positions[result.vertex_ids]
    finite = np.isfinite(expected).all(axis=1)
    assert np.array_equal(mesh.vertices[finite], expected[finite])
    if not mesh.n_faces or not finite.all():
        return
    scale = max(float(np.ptp(mesh.vertices, axis=0).max()), 1e-300)
    for f in np.flatnonzero(face_areas(mesh) <= ZERO * scale**2):
        corners = mesh.vertices[mesh.face_indices[mesh.face_offsets[f]:
                                                  mesh.face_offsets[f + 1]]]
        assert degenerate_corners(corners, scale), (f, corners)


def assert_valid(result, n_input: int) -> None:
    halfedges = HalfedgeMesh.from_connectivity(result.connectivity)
    assert halfedges.problems() == []
    mesh = result.mesh
    assert len(result.vertex_ids) == mesh.n_vertices
    assert np.all(result.vertex_ids < n_input)
    keys = edge_keys(result.connectivity.edges, max(result.connectivity.n_vertices, 1))
    assert len(np.unique(keys)) == len(keys), "an edge appears twice"
    if mesh.n_faces:  # an adversarial embedding may decode to nothing: valid, and empty
        # (NaN positions stay NaN: the topology is checked on finite stand-ins)
        assert_valid_mesh(mesh.with_vertices(np.nan_to_num(mesh.vertices)))
    else:
        assert mesh.n_vertices == 0


# ---------------------------------------------------------------------- strategies
@st.composite
def vertex_positions(draw, n: int) -> np.ndarray:
    """Positions with the degenerate configurations a decode must survive."""
    # a regular sphere of points moved by a drawn offset: shrinking leads to the sphere
    i = np.arange(n) + 0.5
    z, phi = 1.0 - 2.0 * i / max(n, 1), np.pi * (1.0 + 5**0.5) * i
    r = np.sqrt(1.0 - z**2)
    sphere = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    p = sphere + draw(hnp.arrays(np.float64, (n, 3), elements=OFFSET))
    kind = draw(st.sampled_from(["sphere", "generic", "clusters", "collinear", "coplanar",
                                 "coincident"]))
    if kind == "generic":
        p = draw(hnp.arrays(np.float64, (n, 3), elements=COORDINATE, fill=st.nothing()))
    if kind == "clusters" and n:  # rows snapped onto a few of them: coincident points
        labels = draw(hnp.arrays(np.int64, n, elements=st.integers(0, max(n // 3, 1) - 1)))
        p = p[labels]
    elif kind == "collinear":
        p = p[:, :1] * np.array([[0.3, -0.5, 0.8]]) + 0.1
    elif kind == "coplanar":
        p[:, 2] = 0.25
    elif kind == "coincident":
        p[:] = 0.5
    if n and not draw(st.integers(0, 3)):  # NaN rows
        bad = draw(hnp.arrays(bool, n, elements=st.booleans()))
        p[bad] = np.nan
    return p


@st.composite
def embeddings(draw, sizes: tuple[int, int] = (6, 40)):
    n = draw(st.integers(*sizes))
    k = draw(st.sampled_from([4, 8, 16]))
    kp = draw(st.integers(1, 6))
    positions = draw(vertex_positions(n))
    kind = draw(st.sampled_from(["positions", "free", "positions", "duplicated"]))
    x = draw(hnp.arrays(np.float64, (n, k), elements=EMBEDDING, fill=st.nothing()))
    if kind == "positions":  # near vertices are near in the embedding: mesh-like graphs
        spread = draw(st.sampled_from([0.05, 0.0, 0.3]))
        x = np.concatenate([4.0 * np.nan_to_num(positions), spread * x[:, 3:]], axis=1)
        kind = "positions"
    elif kind == "duplicated" and n:  # coincident embeddings: ties and dense clusters
        x = x[draw(hnp.arrays(np.int64, n, elements=st.integers(0, max(n // 4, 1) - 1)))]
    scale = draw(st.sampled_from([1e-3, 1.0, 10.0]))
    x = x * scale
    distance = draw(st.sampled_from(["euclidean", "spacetime", "dot"]))
    special = draw(st.sampled_from([None, None, None, None, None, np.nan, np.inf, -np.inf,
                                    0.0]))
    if special is None and n >= 2:
        d = pairwise_distance(x, distance=distance)[np.triu_indices(n, 1)]
        q = draw(st.sampled_from([0.08, 0.2, 0.3, 0.02, 0.5, 1.0]))
        tau = float(np.quantile(d, q)) + draw(st.sampled_from([-1e-9, 0.0, 1e-9]))
    else:
        tau = float(special if special is not None else draw(st.floats(-10, 10)))
    perm_kind = draw(st.sampled_from(["constant", "free", "positions"]))
    if perm_kind == "free":
        root, prev, nxt = (draw(hnp.arrays(np.float64, (n, kp), elements=EMBEDDING))
                           for _ in range(3))
    elif perm_kind == "constant":  # every cyclic order ties
        root = prev = nxt = np.ones((n, kp))
    else:
        base = np.resize(np.nan_to_num(positions), (n, kp)) if n else np.zeros((0, kp))
        root, prev, nxt = base, np.roll(base, 1, axis=1), -base
    if n and not draw(st.integers(0, 3)):  # NaN and infinite entries
        bad = draw(hnp.arrays(bool, (n, k), elements=st.booleans()))
        x = x.copy()
        x[bad] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    emb = Embeddings(x, tau, root, prev, nxt)
    alive = None if draw(st.integers(0, 3)) else draw(hnp.arrays(bool, n,
                                                                 elements=st.booleans()))
    options = DecodeOptions(
        distance=distance, fallback=draw(st.sampled_from(["angular", "greedy"])),
        unpinch=draw(st.sampled_from(["edge", "vertex"])), uncross=draw(st.booleans()),
        max_sides=draw(st.sampled_from([None, 3, 4])),
        max_degree=draw(st.sampled_from([DecodeOptions.max_degree, 3, 5])),
        reinsert=draw(st.booleans()), flip=draw(st.booleans()),
        flat_delaunay_degrees=draw(st.sampled_from([None, 1.0, 30.0])),
        fit_gain=draw(st.sampled_from([None, 0.0, 0.5])))
    # conditioning points for the fit flips: none, near the vertices, or partly non-finite
    which = draw(st.sampled_from(["none", "cloud", "non-finite"]))
    cloud = None
    if which != "none":
        cloud = draw(hnp.arrays(np.float64, (draw(st.integers(0, 60)), 3),
                                elements=COORDINATE))
        if which == "non-finite" and len(cloud):
            cloud[::3] = np.inf
    return emb, options, alive, positions, cloud


@st.composite
def polyhedra(draw):
    """A closed triangle mesh (a drawn point set's convex hull, outward), the distance
    operands of drawn embeddings, and the flip options."""
    n = draw(st.integers(4, 12))
    points = draw(hnp.arrays(np.float64, (n, 3), elements=COORDINATE))
    if draw(st.booleans()):  # a flattened solid: near-flat quads for the Delaunay rule
        points[:, 2] *= draw(st.sampled_from([1e-3, 0.1]))
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        hull = None
    if hull is None or len(hull.vertices) < 4:
        points = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                           [0, 0, -1]])  # the octahedron
        hull = ConvexHull(points)
    used = np.unique(hull.simplices)
    index = np.full(len(points), -1)
    index[used] = np.arange(len(used))
    positions, triangles = points[used], index[hull.simplices]
    centre = positions.mean(axis=0)
    for t in triangles:  # outward
        a, b, c = positions[t]
        if np.dot(np.cross(b - a, c - a), a - centre) < 0:
            t[[1, 2]] = t[[2, 1]]
    k = draw(st.sampled_from([4, 8]))
    x = draw(hnp.arrays(np.float64, (len(used), k), elements=EMBEDDING))
    if draw(st.booleans()):  # coincident embeddings: many equal-score diagonals
        x = x[draw(hnp.arrays(np.int64, len(used), elements=st.integers(0, 1)))]
    distance = draw(st.sampled_from(["spacetime", "euclidean", "dot"]))
    cloud = None
    if draw(st.booleans()):
        cloud = draw(hnp.arrays(np.float64, (draw(st.integers(1, 40)), 3),
                                elements=COORDINATE))
    options = {"by_score": draw(st.booleans()),
               "flat_degrees": draw(st.sampled_from([None, 1.0, 30.0])),
               "fit_gain": draw(st.sampled_from([None, 0.0, 0.5])),
               "with_positions": draw(st.booleans())}
    return positions, triangles, distance_operands(x, distance), cloud, options


# ---------------------------------------------------------------------- properties
@settings(BOUNDED, max_examples=120)
@given(embeddings())
def test_any_embedding_decodes_to_valid_mesh(case):
    emb, options, alive, positions, points = case
    result = decode(positions, emb, options, alive, points=points)
    assert_valid(result, emb.n_vertices)
    assert_geometry_explained(result, positions)
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


@settings(BOUNDED, max_examples=40)
@given(embeddings(sizes=(0, 5)))
def test_tiny_inputs_decode_to_valid_mesh(case):
    """No vertex, one, two... five: nothing to make a surface from, or a tetrahedron."""
    emb, options, alive, positions, points = case
    result = decode(positions, emb, options, alive, points=points)
    assert_valid(result, emb.n_vertices)
    assert_geometry_explained(result, positions)


@settings(BOUNDED, max_examples=150)
@given(polyhedra())
def test_flips_keep_a_closed_manifold_without_doubled_edges(case):
    """Flipping diagonals of any closed triangle mesh, by any rule, leaves a closed
    oriented manifold on the same vertices with as many triangles, every edge once,
    and every vertex on at least three edges."""
    positions, triangles, operands, cloud, options = case
    n = len(positions)
    before = connectivity_from_faces(list(triangles), n)
    with_positions = options.pop("with_positions")
    after, flips = flip_diagonals(before, operands, positions if with_positions else None,
                                  points=cloud, **options)
    keys = edge_keys(after.edges, n)
    assert len(np.unique(keys)) == len(keys) == len(edge_keys(before.edges, n)), (
        "a flip doubled an edge")
    indices, offsets = after.faces()
    mesh = PolygonMesh(positions, indices, offsets)
    assert_valid_mesh(mesh)
    assert mesh.is_triangle_mesh() and mesh.n_faces == len(triangles)
    assert after.degree.min() >= 3
    if flips == 0:
        assert np.array_equal(np.sort(keys), np.sort(edge_keys(before.edges, n)))


@settings(BOUNDED, max_examples=50)
@given(embeddings(), st.sampled_from([None, 10, 80]), st.booleans(), st.booleans())
def test_the_geometry_stage_keeps_the_guarantee(case, target, flips, guard):
    """Splits, fit and flips of any decode stay a closed oriented manifold; the
    self-intersection shares the stage reports are those of the meshes it takes and
    returns; with the guard, the share never grows."""
    emb, options, alive, positions, points = case
    decoded = decode(positions, emb, options, alive, points=points)
    cloud = points if points is not None else np.zeros((0, 3))
    refined = refine_geometry(decoded.mesh, cloud, None,
                              GeometryOptions(flips=flips, guard=guard, rounds=2),
                              target_vertices=target)
    mesh, stats = refined.mesh, refined.stats
    assert mesh.n_vertices >= decoded.mesh.n_vertices
    if mesh.n_faces:
        assert check_topology(mesh).is_closed_oriented_manifold
        assert np.isfinite(mesh.vertices).all() or not stats["kept"]
    if "intersections_after" in stats:  # the stage ran: its report is the truth
        assert stats["intersections_after"] == self_intersection_fraction(mesh)
        if stats["n_split"] == 0:
            assert stats["intersections_before"] == self_intersection_fraction(decoded.mesh)
        if guard:
            assert stats["intersections_after"] <= stats["intersections_before"]
    if guard and decoded.mesh.n_faces > 1 and np.isfinite(decoded.mesh.vertices).all():
        before = self_intersecting_faces(decoded.mesh).mean()
        assert self_intersecting_faces(mesh).mean() <= before + 1e-12 or stats["n_split"] > 0


def test_splits_leave_a_two_triangle_pillow_alone():
    from spacemesh.geometry.stage import split_longest_edges

    positions = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    pillow = np.array([[0, 1, 2], [0, 2, 1]])
    moved, triangles = split_longest_edges(positions, pillow, 10)
    mesh = PolygonMesh(moved, triangles.reshape(-1), np.arange(0, 3 * len(triangles) + 1, 3))
    assert check_topology(mesh).is_closed_oriented_manifold


@settings(BOUNDED, max_examples=30)
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
