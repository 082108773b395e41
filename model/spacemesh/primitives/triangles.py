"""Triangles of polygons and polygon meshes, keeping each face's orientation.

Convex faces are fanned from a corner chosen so that straight corners (collinear
runs) make no zero-area fan triangles where a fan can avoid them; non-convex faces
are ear-clipped in their best-fit plane, the plane orthogonal to the face's Newell
normal. ``mapbox_earcut`` is used for the
ear clipping when it is installed, with a pure numpy/Python ear clipper otherwise.
Nothing here fails on bad input: a polygon that cannot be ear-clipped (zero area,
self-intersecting) still yields ``n - 2`` triangles, as a fan or forced ears.
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives.keys import edge_keys
from spacemesh.typed import ArrayLike, FloatArray, IntArray

_mapbox_earcut: ModuleType | None
try:  # optional: the C++ earcut, faster on large non-convex polygons
    import mapbox_earcut as _mapbox_earcut
except ImportError:  # pragma: no cover - depends on the environment
    _mapbox_earcut = None

#: Relative tolerance on the sine of a turn below which a corner counts as reflex.
_CONVEX_TOLERANCE = 1e-9
#: Corners turning less than this (sine) count as straight when choosing a fan apex.
_STRAIGHT_SINE = 1e-6


def newell_normal(points: ArrayLike) -> FloatArray:
    """Newell's (unnormalised) normal of a closed polygon.

    Parameters
    ----------
    points : (n, 3) array_like
        The polygon's corners in order.

    Returns
    -------
    (3,) float64
        Twice the vector area: its length is twice the area of a planar polygon and
        it points to the side from which the polygon is counter-clockwise.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)  # (n, 3)
    q = np.roll(p, -1, axis=0)
    return np.cross(p, q).sum(axis=0)


def _plane_basis(normal: FloatArray) -> FloatArray:
    """(2, 3) orthonormal ``u, v`` with ``u x v`` along ``normal`` (which is non-zero)."""
    n = normal / np.linalg.norm(normal)
    axis = np.zeros(3)
    axis[np.argmin(np.abs(n))] = 1.0
    u = np.cross(axis, n)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    return np.stack([u, v])


def _fan(n: int, apex: int = 0) -> IntArray:
    """(n - 2, 3) fan triangles of an n-gon from corner ``apex``, in ring order."""
    j = np.arange(n - 2, dtype=np.int64)
    return np.stack([np.full(n - 2, apex), apex + j + 1, apex + j + 2], axis=1) % n


def _turns(xy: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Sine and angle of the turn at each corner of a 2D ring.

    Returns
    -------
    sine : (n,) float64
        ``cross(e_in, e_out) / (|e_in| |e_out|)``, positive at convex corners.
    angle : (n,) float64
        Signed exterior angle in ``(-pi, pi]``.
    """
    e_in = xy - np.roll(xy, 1, axis=0)  # (n, 2)
    e_out = np.roll(xy, -1, axis=0) - xy
    cross = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
    dot = np.einsum("ij,ij->i", e_in, e_out)
    length = np.linalg.norm(e_in, axis=1) * np.linalg.norm(e_out, axis=1)
    sine = cross / np.where(length > 0, length, 1.0)
    return sine, np.arctan2(cross, dot)


def _is_convex(sine: FloatArray, angle: FloatArray) -> bool:
    """Whether a ring with these turns is convex and winds exactly once."""
    return bool(np.all(sine >= -_CONVEX_TOLERANCE) and abs(angle.sum() - 2 * np.pi) < 1e-6)


def _fan_apex(sine: FloatArray) -> int:
    """The first corner whose two neighbours are both true (not straight) corners.

    A fan from corner ``a`` has a zero-area triangle for every straight corner in the
    runs right after and right before ``a``; a corner between two true corners has
    none, and otherwise the corner with the fewest is taken.
    """
    true_corner = sine > _STRAIGHT_SINE
    score = np.roll(true_corner, 1).astype(np.int64) + np.roll(true_corner, -1)
    return int(np.argmax(score))


def _earcut_triangles(xy: FloatArray) -> IntArray | None:
    """Ear clipping with ``mapbox_earcut``; None when it is missing or drops triangles."""
    if _mapbox_earcut is None:
        return None
    n = len(xy)
    try:
        flat = _mapbox_earcut.triangulate_float64(
            np.ascontiguousarray(xy, dtype=np.float64), np.array([n], dtype=np.uint32)
        )
    except Exception:  # pragma: no cover - earcut is not expected to raise
        return None
    triangles = np.asarray(flat, dtype=np.int64).reshape(-1, 3)
    if len(triangles) != n - 2:
        return None
    a, b, c = xy[triangles[:, 0]], xy[triangles[:, 1]], xy[triangles[:, 2]]
    signed = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    if signed.sum() < 0:  # earcut keeps the input winding; make sure of it
        triangles = triangles[:, ::-1]
    return triangles


def _orient(xy: FloatArray, a: int, b: int, c: int) -> float:
    """Twice the signed area of the 2D triangle ``(a, b, c)``."""
    ax, ay = xy[a]
    bx, by = xy[b]
    cx, cy = xy[c]
    return float((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))


def _ear_clip(xy: FloatArray) -> IntArray:
    """Ear clipping of a counter-clockwise 2D ring; always returns ``n - 2`` triangles.

    A corner is an ear when it is strictly convex and no other non-convex corner lies
    in (or on) its triangle. When a whole pass round the ring finds no ear (the ring
    is degenerate or self-intersecting) the most convex corner is clipped anyway.
    """
    n = len(xy)
    scale = float(np.ptp(xy, axis=0).max()) if n else 0.0
    eps = 1e-12 * scale * scale
    prev = [(i - 1) % n for i in range(n)]
    nxt = [(i + 1) % n for i in range(n)]
    active = np.ones(n, dtype=bool)
    turn = np.array([_orient(xy, prev[i], i, nxt[i]) for i in range(n)])  # (n,)

    def is_ear(i: int) -> bool:
        p, q = prev[i], nxt[i]
        if turn[i] <= eps:
            return False
        candidates = np.flatnonzero(active & (turn <= eps))
        candidates = candidates[(candidates != p) & (candidates != q) & (candidates != i)]
        if candidates.size == 0:
            return True
        pts = xy[candidates]  # (m, 2)
        corners = xy[[p, i, q]]  # (3, 2)
        # Points at the same position as a corner (touching rings) do not block.
        same = np.any(np.all(pts[:, None, :] == corners[None, :, :], axis=2), axis=1)
        pts = pts[~same]
        if pts.size == 0:
            return True
        inside = np.ones(len(pts), dtype=bool)
        for k in range(3):
            a, b = corners[k], corners[(k + 1) % 3]
            side = (b[0] - a[0]) * (pts[:, 1] - a[1]) - (b[1] - a[1]) * (pts[:, 0] - a[0])
            inside &= side >= -eps
        return not bool(inside.any())

    triangles: list[tuple[int, int, int]] = []
    remaining, i, stall = n, 0, 0
    while remaining > 3:
        if stall >= remaining:  # no proper ear: force the most convex corner
            alive = np.flatnonzero(active)
            i = int(alive[np.argmax(turn[alive])])
            forced = True
        else:
            forced = is_ear(i)
        if forced:
            p, q = prev[i], nxt[i]
            triangles.append((p, i, q))
            active[i] = False
            nxt[p], prev[q] = q, p
            turn[p] = _orient(xy, prev[p], p, q)
            turn[q] = _orient(xy, p, q, nxt[q])
            remaining -= 1
            stall = 0
            i = q
        else:
            stall += 1
            i = nxt[i]
    triangles.append((prev[i], i, nxt[i]))
    return np.array(triangles, dtype=np.int64).reshape(-1, 3)


def triangulate_polygon(points3d: ArrayLike) -> IntArray:
    """Triangulate one polygon in 3D, keeping its orientation.

    Convex polygons are fanned from a corner whose neighbours are not straight,
    which keeps collinear runs from making zero-area triangles. Non-convex ones are
    projected onto the plane orthogonal to their Newell normal and ear-clipped
    (``mapbox_earcut`` when installed, else a built-in ear clipper). Never fails:
    a polygon with zero area is fanned from its first corner.

    Parameters
    ----------
    points3d : (n, 3) array_like
        The polygon's corners in order (counter-clockwise seen from the side its
        Newell normal points to).

    Returns
    -------
    (n - 2, 3) int64
        Corner indices of the triangles, each in the polygon's cyclic order, so
        every triangle is counter-clockwise about the polygon normal. Empty for
        ``n < 3``.
    """
    p = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)  # (n, 3)
    n = len(p)
    if n < 3:
        return np.zeros((0, 3), dtype=np.int64)
    if n == 3:
        return np.array([[0, 1, 2]], dtype=np.int64)
    if not np.all(np.isfinite(p)):
        return _fan(n)
    normal = newell_normal(p - p.mean(axis=0))
    length = float(np.linalg.norm(normal))
    extent = float(np.ptp(p, axis=0).max())
    if not length > 1e-14 * max(extent, 1e-300) ** 2:
        return _fan(n)
    xy = (p - p.mean(axis=0)) @ _plane_basis(normal).T  # (n, 2), counter-clockwise
    sine, angle = _turns(xy)
    if _is_convex(sine, angle):
        return _fan(n, _fan_apex(sine))
    triangles = _earcut_triangles(xy)
    if triangles is None:
        triangles = _ear_clip(xy)
    return triangles


def _corner_turns(
    mesh: PolygonMesh, normals: FloatArray
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Sine and signed exterior angle of every corner about its face normal.

    Returns
    -------
    sine : (S,) float64
    angle : (S,) float64
    prev_corner : (S,) int64
        The previous corner of the same face.
    """
    start = np.repeat(mesh.face_offsets[:-1], mesh.face_sizes)  # (S,)
    size = np.maximum(np.repeat(mesh.face_sizes, mesh.face_sizes), 1)
    position = np.arange(mesh.face_indices.size, dtype=np.int64)
    prev_corner = start + (position - start - 1) % size
    here = mesh.vertices[mesh.face_indices]  # (S, 3)
    n = normals[mesh.face_of_corner]  # (S, 3) unit, or zero for degenerate faces
    # Sides projected on the face plane, as triangulate_polygon sees them: the turns of
    # a non-planar face then add up to exactly 2 pi times its winding number.
    e_in = here - mesh.vertices[mesh.face_indices[prev_corner]]
    e_out = mesh.vertices[mesh.face_indices[mesh.next_corner]] - here
    e_in = e_in - np.einsum("ij,ij->i", e_in, n)[:, None] * n
    e_out = e_out - np.einsum("ij,ij->i", e_out, n)[:, None] * n
    cross = np.einsum("ij,ij->i", np.cross(e_in, e_out), n)
    dot = np.einsum("ij,ij->i", e_in, e_out)
    length = np.linalg.norm(e_in, axis=1) * np.linalg.norm(e_out, axis=1)
    return cross / np.where(length > 0, length, 1.0), np.arctan2(cross, dot), prev_corner


def _fan_faces(mesh: PolygonMesh, faces: IntArray, apex: IntArray) -> IntArray:
    """(T, 3) fan triangles of the given faces, each from its local corner ``apex``."""
    sizes = mesh.face_sizes[faces]  # (k,)
    n_tri = sizes - 2
    owner = np.repeat(np.arange(len(faces)), n_tri)  # (T,)
    first = np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    j = np.arange(owner.size, dtype=np.int64) - first  # triangle number inside the face
    size = sizes[owner]
    base = mesh.face_offsets[faces][owner]
    local = np.stack([apex[owner], apex[owner] + j + 1, apex[owner] + j + 2], axis=1)
    return mesh.face_indices[base[:, None] + local % size[:, None]]


def triangulate_faces(mesh: PolygonMesh) -> tuple[IntArray, IntArray]:
    """Triangulate every face of a polygon mesh, keeping its orientation.

    Triangle meshes are returned as they are. Convex faces are fanned (vectorised)
    from a corner between two true corners (see above); only non-convex faces go through
    :func:`triangulate_polygon` one by one. Faces with fewer than three corners
    give no triangles.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    triangles : (T, 3) int64
        Vertex indices, counter-clockwise like their faces; a face with ``k``
        corners gives ``k - 2`` triangles. Sorted by source face.
    source_face : (T,) int64
        The face each triangle came from.
    """
    sizes = mesh.face_sizes  # (F,)
    if mesh.n_faces == 0:
        return np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64)
    if np.all(sizes == 3):
        return mesh.face_indices.reshape(-1, 3).copy(), np.arange(mesh.n_faces, dtype=np.int64)

    normals = mesh.face_normals()  # (F, 3)
    sine, angle, prev_corner = _corner_turns(mesh, normals)
    owner = mesh.face_of_corner
    reflex = np.bincount(owner, weights=sine < -_CONVEX_TOLERANCE, minlength=mesh.n_faces)
    winding = np.bincount(owner, weights=angle, minlength=mesh.n_faces)
    has_normal = np.linalg.norm(normals, axis=1) > 0
    convex = (sizes == 3) | (
        (sizes > 3) & has_normal & (reflex == 0) & (np.abs(winding - 2 * np.pi) < 1e-6)
    )

    convex_faces = np.flatnonzero(convex)
    # Fan apex of each convex face (see _fan_apex): sort corners by (face, -score).
    true_corner = sine > _STRAIGHT_SINE
    score = true_corner[prev_corner].astype(np.int64) + true_corner[mesh.next_corner]
    order = np.lexsort((-score, owner))
    apex_corner = order[mesh.face_offsets[:-1][convex_faces]]
    apex = np.where(sizes[convex_faces] == 3, 0, apex_corner - mesh.face_offsets[convex_faces])
    parts = [_fan_faces(mesh, convex_faces, apex)]
    sources = [np.repeat(convex_faces, sizes[convex_faces] - 2)]

    for f in np.flatnonzero(~convex & (sizes > 3)):
        face = mesh.face_indices[mesh.face_offsets[f] : mesh.face_offsets[f + 1]]
        local = triangulate_polygon(mesh.vertices[face])
        parts.append(face[local])
        sources.append(np.full(len(local), f, dtype=np.int64))

    triangles = np.concatenate(parts).astype(np.int64).reshape(-1, 3)
    source_face = np.concatenate(sources).astype(np.int64)
    order = np.argsort(source_face, kind="stable")
    return triangles[order], source_face[order]


def _diagonal_keys(
    mesh: PolygonMesh, triangles: IntArray, source: IntArray
) -> tuple[IntArray, IntArray]:
    """The inner edges (diagonals) a triangulation adds, one row per face and diagonal.

    Returns
    -------
    face : (D,) int64
        The face each diagonal lies in.
    key : (D,) int64
        ``min * V + max`` of its two vertices.
    """
    n = max(mesh.n_vertices, 1)
    a = triangles.reshape(-1)  # (3T,) edge origins
    b = triangles[:, [1, 2, 0]].reshape(-1)  # (3T,) edge targets
    face = np.repeat(source, 3)  # (3T,)
    # Position of each vertex within its face, found by (face, vertex) lookup.
    corner_key = mesh.face_of_corner * n + mesh.face_indices  # (S,)
    order = np.argsort(corner_key, kind="stable")
    local = (np.arange(mesh.face_indices.size) - mesh.face_offsets[mesh.face_of_corner])[order]
    sorted_key = corner_key[order]
    pos_a = local[np.searchsorted(sorted_key, face * n + a)]
    pos_b = local[np.searchsorted(sorted_key, face * n + b)]
    size = mesh.face_sizes[face]
    step = (pos_b - pos_a) % size
    inner = (step != 1) & (step != size - 1)
    key = edge_keys(np.stack([a[inner], b[inner]], axis=1), mesh.n_vertices)
    pairs = np.unique(np.stack([face[inner], key], axis=1), axis=0)  # (D, 2)
    return pairs[:, 0], pairs[:, 1]


def _fan_order(points: FloatArray) -> list[int]:
    """Fan apexes of a polygon, those whose fan flips the fewest triangles first."""
    n = len(points)
    normal = newell_normal(points - points.mean(axis=0))
    flips = []
    for apex in range(n):
        tri = points[_fan(n, apex)]  # (n - 2, 3, 3)
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        flips.append(int(np.sum(cross @ normal <= 0)))
    return sorted(range(n), key=lambda apex: (flips[apex], apex))


def triangulate_manifold(mesh: PolygonMesh) -> tuple[FloatArray, IntArray, IntArray]:
    """Triangulate a polygon mesh so that the triangles are as manifold as the polygons.

    :func:`triangulate_faces` chooses each face's diagonals from its geometry alone,
    so a diagonal can coincide with an edge of the mesh or with a diagonal of another
    face (two faces sharing three vertices, as small or folded polygon meshes do); the
    triangle mesh then has an edge with four triangles although the polygon mesh is a
    valid manifold. Here every face with such a diagonal is re-triangulated: as a fan
    from the apex, of those whose diagonals are all new edges, that flips the fewest
    triangles against the face normal; when no fan is free, a new vertex at the face's
    centroid is fanned to every side, which is always free. The result is then an
    edge- and vertex-manifold, consistently oriented triangle mesh wherever the polygon
    mesh is one (a closed oriented manifold stays closed, oriented and manifold).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    vertices : (V + C, 3) float64
        The mesh's vertices, then one centroid per face that needed one (``C`` is
        zero unless no fan of some face was free).
    triangles : (T, 3) int64
        Counter-clockwise like their faces; sorted by source face.
    source_face : (T,) int64
        The face each triangle came from.
    """
    triangles, source = triangulate_faces(mesh)
    if triangles.size == 0 or not np.any(mesh.face_sizes > 3):
        return mesh.vertices, triangles, source
    diag_face, diag_key = _diagonal_keys(mesh, triangles, source)
    side_key = edge_keys(mesh.edges, mesh.n_vertices)
    keys, owners = np.unique(diag_key, return_counts=True)
    shared = keys[owners > 1]
    suspect = np.unique(diag_face[np.isin(diag_key, side_key) | np.isin(diag_key, shared)])
    if suspect.size == 0:
        return mesh.vertices, triangles, source

    sides = set(side_key.tolist())
    uses = dict(zip(keys.tolist(), owners.tolist(), strict=True))  # diagonal -> faces using it
    face_diagonals: dict[int, list[int]] = {int(f): [] for f in suspect}
    for f, key in zip(diag_face.tolist(), diag_key.tolist(), strict=True):
        if f in face_diagonals:
            face_diagonals[f].append(key)

    vertices = [mesh.vertices]
    replaced: list[int] = []
    parts: list[IntArray] = []
    part_sources: list[IntArray] = []
    next_vertex = mesh.n_vertices
    for f in face_diagonals:
        own = face_diagonals[f]
        if not any(k in sides or uses[k] > 1 for k in own):
            continue  # freed by a face re-triangulated before it
        for k in own:
            uses[k] -= 1
        face = mesh.face_indices[mesh.face_offsets[f] : mesh.face_offsets[f + 1]]
        size = len(face)
        chosen: IntArray | None = None
        chosen_keys: list[int] = []
        for apex in _fan_order(mesh.vertices[face]):
            others = face[(apex + np.arange(2, size - 1)) % size]  # the apex's non-neighbours
            spokes = np.stack([np.full(len(others), face[apex]), others], axis=1)
            fan_keys = edge_keys(spokes, mesh.n_vertices).tolist()
            if not any(k in sides or uses.get(k, 0) > 0 for k in fan_keys):
                chosen, chosen_keys = face[_fan(size, apex)], fan_keys
                break
        if chosen is None:  # no free fan: a centroid vertex, whose spokes are all new
            vertices.append(mesh.vertices[face].mean(axis=0, keepdims=True))
            chosen = np.stack([face, np.roll(face, -1), np.full(size, next_vertex)], axis=1)
            next_vertex += 1
        for k in chosen_keys:
            uses[k] = uses.get(k, 0) + 1
        replaced.append(f)
        parts.append(chosen)
        part_sources.append(np.full(len(chosen), f, dtype=np.int64))
    if not replaced:
        return mesh.vertices, triangles, source
    keep = ~np.isin(source, replaced)
    triangles = np.concatenate([triangles[keep], *parts]).astype(np.int64)
    source = np.concatenate([source[keep], *part_sources])
    order = np.argsort(source, kind="stable")
    return np.concatenate(vertices), triangles[order], source[order]


__all__ = ["newell_normal", "triangulate_faces", "triangulate_manifold", "triangulate_polygon"]


def triangles_of(mesh: PolygonMesh) -> tuple[IntArray, IntArray]:
    """Triangles of a polygon mesh and the face each comes from.

    The one way every module reads a polygon mesh as triangles
    (:func:`triangulate_faces`: triangle meshes as they are, convex faces fanned,
    others ear-clipped).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    triangles : (T, 3) int64
    source_face : (T,) int64
    """
    if mesh.is_triangle_mesh():
        return mesh.face_indices.reshape(-1, 3), np.arange(mesh.n_faces, dtype=np.int64)
    return triangulate_faces(mesh)


def signed_volume(mesh: PolygonMesh) -> float:
    """Signed enclosed volume (positive for a closed mesh oriented outward).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    float
    """
    tri, _ = triangles_of(mesh)
    v = mesh.vertices - mesh.vertices.mean(axis=0)
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]  # (T, 3) each
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def triangle_areas(vertices: FloatArray, triangles: IntArray) -> FloatArray:
    """(T,) area of each triangle ``vertices[triangles[t]]``."""
    p = vertices[triangles]  # (T, 3, 3)
    return np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1) / 2


def surface_area(mesh: PolygonMesh) -> float:
    """Total area of the triangulated faces.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    float
    """
    tri, _ = triangles_of(mesh)
    return float(triangle_areas(mesh.vertices, tri).sum())


def fan_volumes(mesh: PolygonMesh) -> FloatArray:
    """(S,) each corner's share of the signed volume, every face fanned from its first corner.

    Corner ``c`` of a face with first corner ``f`` contributes ``f . (c x next(c)) / 6``
    (O(corners), no triangulation); summed over a closed mesh this is its enclosed volume,
    positive when the faces wind counter-clockwise seen from outside, exact for planar
    polygons of any shape. Over an open mesh the sum still tells the dominant orientation.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    (S,) float64
    """
    v = mesh.vertices
    first = v[np.repeat(mesh.face_indices[mesh.face_offsets[:-1]], mesh.face_sizes)]  # (S, 3)
    a, b = v[mesh.face_indices], v[mesh.face_indices[mesh.next_corner]]  # (S, 3) each
    return np.einsum("ij,ij->i", first, np.cross(a, b)) / 6.0
