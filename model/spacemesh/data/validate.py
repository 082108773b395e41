"""The strict validator applied to every shape before it is stored.

A stored shape must be a closed, edge- and vertex-manifold, consistently and
outward oriented, single-component polygon mesh without degenerate faces,
without self-intersections and with (nearly) planar polygons.

Connectivity is checked with our own :func:`spacemesh.topology.check_topology`;
manifold3d is never trusted for this (it silently splits pinched edges).

Tolerances, in the units of a normalised mesh (longest axis spans [-1, 1]; meshes
in any other frame are measured relative to half their longest bounding-box side):

``DUPLICATE_TOLERANCE = 1e-6``
    Two distinct vertices closer than this are a repeated position. Shards store
    float32 positions (spacing 1.2e-7 near 1), so anything closer than ~8 ulps
    could merge or swap order on storage.
``MIN_ALTITUDE = 1e-5``
    A triangle whose smallest altitude (twice its area over its longest side) is
    below this is a needle or a cap. Its normal is then decided by coordinate
    differences of fewer than ~80 float32 ulps, so storage alone can turn it by
    about a degree, and its area is numerically zero at the scale of the shape.
    This is deliberately a *numerical* test, not a quality test: real CAD
    tessellations (e.g. ../shared/meshes ADIS16480.STL, 1002_tray_bottom.STL) have
    legitimate 0.007-0.03 degree needles along long cylinder flanks, with altitudes
    of 1e-4 (smallest altitude of any triangle: 1.2e-4 and 7.5e-5), and those are
    kept; collinear caps (altitude 0, as in gear_spur2.stl) are not.
``MIN_EDGE = 1e-5``
    Polygon sides shorter than this are degenerate (the polygon analogue).
``MAX_NONPLANARITY = 0.2``
    Half the spread of a polygon's corners along its Newell normal, relative to the
    polygon's diameter. A square folded along its diagonal by an angle t scores
    0.5 sin(t / 2), so 0.2 is a fold of about 47 degrees. Real quad meshes reach
    0.1-0.15 (../shared/meshes: fandisk_quads 0.097, horse_quad 0.143) and
    subdivision control meshes are bent by design (fish_control_mesh 0.185); these
    are real training data. Beyond 0.2 a "face" is really two.
``FOLD_DEGREES = 0.01``
    Two faces meeting at an edge with an opening angle below this lie on top of each
    other: at 1e-3 from the edge they are within 2e-7, so float32 rounding can make
    them cross. Face-pair intersection tests skip such pairs (they share an edge).

Self-intersections: pymeshlab's ``compute_selection_by_self_intersections_per_face``
selects candidates, and every candidate pair is confirmed by our own triangle-triangle
test (segment-triangle tests, plus a separating-axis test for coplanar pairs; touching
within 1e-9 counts). The confirmation is needed because VCG's test reports separated
coplanar triangles as intersecting: in a trial of 100 QEM-decimated CAD shapes it
flagged 10, of which 8 were such false positives.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import signed_volume, triangles_of
from spacemesh.topology import check_topology
from spacemesh.typed import FloatArray, IntArray

DUPLICATE_TOLERANCE = 1e-6
MIN_AREA = 1e-12
MIN_ALTITUDE = 1e-5
MIN_EDGE = 1e-5
MAX_NONPLANARITY = 0.2
FOLD_DEGREES = 0.01

#: Every rejection cause this module can report, in a stable order.
CAUSES = (
    "empty",
    "unreferenced_vertices",
    "malformed_face",
    "open_boundary",
    "non_manifold_edge",
    "non_manifold_vertex",
    "inconsistent_orientation",
    "multiple_components",
    "inward_orientation",
    "duplicate_vertex",
    "zero_area_face",
    "sliver_face",
    "non_planar_face",
    "folded_edge",
    "self_intersection",
)


def _scale(vertices: FloatArray) -> float:
    """Half the longest bounding-box side (1 for a normalised mesh)."""
    if len(vertices) == 0:
        return 1.0
    extent = float(np.ptp(vertices, axis=0).max()) / 2
    return extent if extent > 0 else 1.0


def has_duplicate_positions(vertices: FloatArray, tolerance: float) -> bool:
    """Whether two distinct vertices lie within ``tolerance`` of each other."""
    if len(vertices) < 2:
        return False
    from scipy.spatial import cKDTree

    return bool(cKDTree(vertices).query_pairs(tolerance, output_type="ndarray").size)


def _triangle_degeneracy(vertices: FloatArray, tri: IntArray, scale: float) -> tuple[bool, bool]:
    """(any zero-area triangle, any needle/cap triangle) among ``tri``."""
    p = vertices[tri]  # (T, 3, 3)
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    double_area = np.linalg.norm(cross, axis=1) / scale**2  # (T,)
    sides = np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2).max(axis=1) / scale  # (T,)
    zero = double_area < 2 * MIN_AREA
    altitude = double_area / np.where(sides > 0, sides, 1.0)
    return bool(zero.any()), bool(np.any(~zero & (altitude < MIN_ALTITUDE)))


def _polygon_defects(mesh: PolygonMesh, scale: float) -> tuple[bool, bool, bool]:
    """(zero area, short side, non-planar) among the faces with more than 3 sides."""
    sizes = mesh.face_sizes
    big = np.flatnonzero(sizes > 3)
    if big.size == 0:
        return False, False, False
    v = mesh.vertices / scale
    normals = np.zeros((len(big), 3))
    zero = short = bent = False
    for row, f in enumerate(big):
        ring = v[mesh.face_indices[mesh.face_offsets[f] : mesh.face_offsets[f + 1]]]  # (n, 3)
        newell = np.cross(ring, np.roll(ring, -1, axis=0)).sum(axis=0)
        area = np.linalg.norm(newell) / 2
        sides = np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1)
        if area < MIN_AREA:
            zero = True
            continue
        short |= bool(sides.min() < MIN_EDGE)
        normals[row] = newell / (2 * area)
        offsets = (ring - ring.mean(axis=0)) @ normals[row]
        diameter = np.linalg.norm(ring[:, None] - ring[None], axis=2).max()
        bent |= bool(np.ptp(offsets) / 2 > MAX_NONPLANARITY * diameter)
    return zero, short, bent


def _folded(mesh: PolygonMesh) -> bool:
    """Whether two faces meet at an edge with an opening angle below FOLD_DEGREES."""
    he = mesh.halfedges  # (S, 2)
    face = mesh.face_of_corner
    key = np.minimum(he[:, 0], he[:, 1]) * mesh.n_vertices + np.maximum(he[:, 0], he[:, 1])
    order = np.argsort(key, kind="stable")
    sk = key[order]
    pair = np.flatnonzero(sk[1:] == sk[:-1])
    if pair.size == 0:
        return False
    normals = mesh.face_normals()
    f1, f2 = face[order[pair]], face[order[pair + 1]]
    cos = np.einsum("ij,ij->i", normals[f1], normals[f2])
    return bool(np.any(cos < -np.cos(np.radians(FOLD_DEGREES))))


# ---------------------------------------------------------------- self-intersections
def _segment_hits_triangle(p0, p1, a, b, c, eps: float) -> bool:
    """Whether segment p0-p1 meets triangle abc (touching within eps counts)."""
    e1, e2 = b - a, c - a
    d = p1 - p0
    n = np.cross(e1, e2)
    nn = np.linalg.norm(n)
    if nn == 0:
        return False
    n = n / nn
    s0, s1 = float((p0 - a) @ n), float((p1 - a) @ n)
    if (s0 > eps and s1 > eps) or (s0 < -eps and s1 < -eps):
        return False
    if abs(s0 - s1) <= eps:  # segment in the plane: left to the coplanar test
        return False
    t = s0 / (s0 - s1)
    x = p0 + t * d
    # Inside test with edge normals in the plane, tolerant by eps.
    for u, w in ((a, b), (b, c), (c, a)):
        edge = w - u
        inward = np.cross(n, edge)
        inward /= max(np.linalg.norm(inward), 1e-300)
        if float((x - u) @ inward) < -eps:
            return False
    return True


def _coplanar_overlap(ta: FloatArray, tb: FloatArray, normal: FloatArray, eps: float) -> bool:
    """Separating-axis test of two coplanar triangles (touching within eps counts)."""
    axis = int(np.argmax(np.abs(normal)))
    keep = [k for k in range(3) if k != axis]
    a2, b2 = ta[:, keep], tb[:, keep]
    for poly in (a2, b2):
        for k in range(3):
            e = poly[(k + 1) % 3] - poly[k]
            n = np.array([-e[1], e[0]])
            length = np.linalg.norm(n)
            if length == 0:
                continue
            n /= length
            pa, pb = a2 @ n, b2 @ n
            if pa.max() < pb.min() - eps or pb.max() < pa.min() - eps:
                return False
    return True


def triangles_intersect(ta: FloatArray, tb: FloatArray, eps: float = 1e-9) -> bool:
    """Whether two triangles intersect; call with triangles that share no vertex.

    Parameters
    ----------
    ta, tb : (3, 3) float64
        Corner positions.
    eps : float
        Distance below which touching counts as intersecting.

    Returns
    -------
    bool
    """
    na = np.cross(ta[1] - ta[0], ta[2] - ta[0])
    nb = np.cross(tb[1] - tb[0], tb[2] - tb[0])
    la, lb = np.linalg.norm(na), np.linalg.norm(nb)
    if la == 0 or lb == 0:
        return False
    na, nb = na / la, nb / lb
    da = (tb - ta[0]) @ na  # (3,) distances of b's corners to a's plane
    db = (ta - tb[0]) @ nb
    if np.all(da > eps) or np.all(da < -eps) or np.all(db > eps) or np.all(db < -eps):
        return False
    if np.all(np.abs(da) <= eps) and np.all(np.abs(db) <= eps):
        return _coplanar_overlap(ta, tb, na, eps)
    for s, t in ((ta, tb), (tb, ta)):
        for k in range(3):
            if _segment_hits_triangle(s[k], s[(k + 1) % 3], t[0], t[1], t[2], eps):
                return True
    return False


def _shrink(points: FloatArray, factor: float) -> FloatArray:
    """Shrink a triangle towards its centroid (so shared corners no longer touch)."""
    centre = points.mean(axis=0)
    return centre + (points - centre) * (1.0 - factor)


def pymeshlab_selected_triangles(vertices: FloatArray, tri: IntArray) -> IntArray:
    """Triangles that pymeshlab's self-intersection filter selects (a superset of the
    crossing ones; the independent check of issue 35)."""
    import pymeshlab

    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=vertices, face_matrix=tri.astype(np.int32)))
    meshset.compute_selection_by_self_intersections_per_face()
    return np.flatnonzero(meshset.current_mesh().face_selection_array())


def find_self_intersection(
    vertices: FloatArray, tri: IntArray, source_face: IntArray | None = None
) -> tuple[int, int] | None:
    """The first confirmed pair of intersecting triangles, or None.

    Triangles of the same polygon face (same ``source_face``) are not compared.
    Pairs that share corners are shrunk by 1e-6 of their size before testing, so
    that the shared corner or edge itself does not count.

    Parameters
    ----------
    vertices : (V, 3) float64
    tri : (T, 3) int64
    source_face : (T,) int64, optional

    Returns
    -------
    (int, int) or None
        Indices of two intersecting triangles.
    """
    candidates = pymeshlab_selected_triangles(vertices, tri)
    if candidates.size < 2:
        return None
    scale = _scale(vertices)
    eps = 1e-9 * scale
    pts = vertices[tri[candidates]]  # (C, 3, 3)
    lo, hi = pts.min(axis=1) - eps, pts.max(axis=1) + eps
    for i in range(len(candidates)):
        overlap = np.all((lo[i + 1 :] <= hi[i]) & (hi[i + 1 :] >= lo[i]), axis=1)
        for j in np.flatnonzero(overlap) + i + 1:
            fa, fb = candidates[i], candidates[j]
            if source_face is not None and source_face[fa] == source_face[fb]:
                continue
            ta, tb = pts[i], pts[j]
            if np.intersect1d(tri[fa], tri[fb]).size:
                ta, tb = _shrink(ta, 1e-6), _shrink(tb, 1e-6)
            if triangles_intersect(ta, tb, eps):
                return int(fa), int(fb)
    return None


# ---------------------------------------------------------------- the validator
def validate_mesh(mesh: PolygonMesh, *, check_intersections: bool = True) -> list[str]:
    """Every reason to reject ``mesh`` (empty when it may be stored).

    Parameters
    ----------
    mesh : PolygonMesh
    check_intersections : bool
        Run the (slowest) self-intersection test.

    Returns
    -------
    list of str
        Causes from :data:`CAUSES`, in that order.
    """
    if mesh.n_faces == 0 or mesh.n_vertices == 0:
        return ["empty"]
    report = check_topology(mesh)
    causes: list[str] = []
    if report.n_unreferenced_vertices:
        causes.append("unreferenced_vertices")
    if report.n_small_faces or report.n_repeated_vertex_faces:
        causes.append("malformed_face")
        return causes  # nothing below is meaningful for such faces
    if report.n_boundary_edges:
        causes.append("open_boundary")
    if report.n_nonmanifold_edges:
        causes.append("non_manifold_edge")
    if report.n_nonmanifold_vertices:
        causes.append("non_manifold_vertex")
    if report.n_misoriented_edges:
        causes.append("inconsistent_orientation")
    if report.n_components != 1:
        causes.append("multiple_components")
    closed = not causes
    if closed and signed_volume(mesh) <= 0:
        causes.append("inward_orientation")
    scale = _scale(mesh.vertices)
    if has_duplicate_positions(mesh.vertices / scale, DUPLICATE_TOLERANCE):
        causes.append("duplicate_vertex")
    tri_faces = np.flatnonzero(mesh.face_sizes == 3)
    tri_zero, tri_sliver = _triangle_degeneracy(
        mesh.vertices,
        mesh.face_indices[mesh.face_offsets[tri_faces][:, None] + np.arange(3)],
        scale,
    )
    poly_zero, poly_short, poly_bent = _polygon_defects(mesh, scale)
    if tri_zero or poly_zero:
        causes.append("zero_area_face")
    if tri_sliver or poly_short:
        causes.append("sliver_face")
    if poly_bent:
        causes.append("non_planar_face")
    if report.is_edge_manifold and _folded(mesh):
        causes.append("folded_edge")
    if check_intersections and not (tri_zero or poly_zero):
        tri, source = triangles_of(mesh)
        if find_self_intersection(mesh.vertices, tri, source) is not None:
            causes.append("self_intersection")
    return causes
