"""Tessellation styles: how a CSG solid becomes the mesh that is stored.

- ``qem``: the solid is refined to a dense triangle mesh, then pymeshlab's quadric
  edge collapse (topology preserved, planar quadrics) brings it down to the target
  vertex count, and edges between nearly coplanar triangles are flipped to the
  Delaunay diagonal (:func:`delaunay_flip_flat`): where both diagonals of a flat quad
  give the same surface, the one QEM's collapse order left is arbitrary, and the
  stored connectivity should be a function of the shape.
- ``planar``: a minimal planar-decimated polygon mesh, as Blender's planar
  decimation makes one: adjacent facets within a small angle merge into one n-gon,
  and vertices left between only two faces are dissolved.
- ``isotropic``: pymeshlab isotropic explicit remeshing at an edge length that
  gives slightly more vertices than the target, then a short QEM collapse to it.
- ``quad``: quad-dominant. The isotropic mesh's triangles are paired into convex,
  nearly planar quads (:func:`pair_triangles`); this is triangle pairing, not a
  field-aligned remesh like Instant Meshes (see docs/DATA.md).
- ``farthest``: the vertices the serving pipeline would choose (feature-weighted
  farthest points of a uniform sample of the surface, as ``start=points`` does), joined
  as the surface joins them: the restricted Delaunay triangulation on a dense copy of
  the solid (:mod:`spacemesh.data.voronoi`). Trains the connectivity network on the
  vertex sets it meets at inference; a result whose genus is not the solid's is refused.

Every style takes the solid, the target vertex count and the shape's random
generator, and returns a :class:`~spacemesh.mesh.PolygonMesh`. Styles do not
validate; :mod:`spacemesh.data.validate` does.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from spacemesh.data.shapes import solid_to_mesh
from spacemesh.data.voronoi import restricted_delaunay
from spacemesh.geometry import farthest_point_sampling, feature_weights
from spacemesh.geometry.policy import FLAT_FLIP_DEGREES
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface, triangle_normals, unit_rows
from spacemesh.runtime.options import FEATURE_BOOST
from spacemesh.topology import check_topology
from spacemesh.typed import IntArray

#: Oversampling of the dense mesh that QEM starts from (vertices per target vertex).
QEM_DENSITY = 3.0


#: Passes of pymeshlab's flip filter at most (one pass does not re-queue the edges its
#: flips make non-Delaunay; three to four passes settle the qem shapes).
FLAT_FLIP_PASSES = 8


def _meshset(mesh: PolygonMesh):
    import pymeshlab

    meshset = pymeshlab.MeshSet()
    faces = mesh.face_indices.reshape(-1, 3).astype(np.int32)
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=mesh.vertices, face_matrix=faces))
    return meshset


def _current(meshset) -> PolygonMesh:
    current = meshset.current_mesh()
    return PolygonMesh.from_faces(current.vertex_matrix(), current.face_matrix())


def _edge_length_for(area: float, n_vertices: float) -> float:
    """Edge length of an equilateral triangulation of ``area`` with ``n_vertices``."""
    # A closed triangle mesh has about 2V faces of area sqrt(3)/4 L^2 each.
    return float(np.sqrt(2.0 * area / (np.sqrt(3.0) * max(n_vertices, 4.0))))


def _faces_for(n_vertices: int, genus: int) -> int:
    """Faces of a closed triangle mesh with ``n_vertices`` and ``genus`` (Euler)."""
    return max(4, 2 * n_vertices - 4 + 4 * genus)


def _qem(meshset, target_vertices: int, genus: int) -> None:
    meshset.meshing_decimation_quadric_edge_collapse(
        targetfacenum=_faces_for(target_vertices, genus),
        qualitythr=0.5,
        preserveboundary=True,
        preservenormal=True,
        preservetopology=True,
        optimalplacement=True,
        planarquadric=True,
        autoclean=True,
    )


def delaunay_flip_flat(meshset, max_angle_degrees: float = FLAT_FLIP_DEGREES) -> None:
    """Flip edges between nearly coplanar triangles to the locally Delaunay diagonal.

    pymeshlab's planar flip optimisation with the Delaunay criterion: an edge whose two
    triangles' normals are within ``max_angle_degrees`` is flipped when its opposite
    angles sum to more than ``pi``. One pass of the filter does not revisit the edges
    its own flips made non-Delaunay, so it runs until the faces stop changing (at most
    :data:`FLAT_FLIP_PASSES` times). Vertices do not move (no relaxation), so the
    surface changes by at most the flat quads' fold.

    Parameters
    ----------
    meshset : pymeshlab.MeshSet
        Its current mesh is changed in place.
    max_angle_degrees : float
    """
    faces = meshset.current_mesh().face_matrix()
    for _ in range(FLAT_FLIP_PASSES):
        meshset.meshing_edge_flip_by_planar_optimization(
            pthreshold=max_angle_degrees, planartype="delaunay", iterations=0
        )
        flipped = meshset.current_mesh().face_matrix()
        if np.array_equal(flipped, faces):
            return
        faces = flipped


def _dense(solid, target_vertices: int) -> PolygonMesh:
    """The solid refined so it has about QEM_DENSITY times the target vertices."""
    length = _edge_length_for(solid.surface_area(), QEM_DENSITY * target_vertices)
    return solid_to_mesh(solid.refine_to_length(length))


def qem(solid, target_vertices: int, rng: np.random.Generator) -> PolygonMesh:
    """Quadric edge collapse of a dense mesh down to ``target_vertices``, flat edges
    flipped to Delaunay.

    Parameters
    ----------
    solid : manifold3d.Manifold
    target_vertices : int
    rng : numpy.random.Generator
        Unused (QEM is deterministic); kept for a uniform signature.

    Returns
    -------
    PolygonMesh
        A triangle mesh.
    """
    meshset = _meshset(_dense(solid, target_vertices))
    _qem(meshset, target_vertices, solid.genus())
    delaunay_flip_flat(meshset)
    return _current(meshset)


def isotropic(solid, target_vertices: int, rng: np.random.Generator) -> PolygonMesh:
    """Isotropic remeshing, then a short collapse to ``target_vertices``.

    Parameters
    ----------
    solid : manifold3d.Manifold
    target_vertices : int
    rng : numpy.random.Generator
        Unused; kept for a uniform signature.

    Returns
    -------
    PolygonMesh
        A triangle mesh.
    """
    import pymeshlab

    meshset = _meshset(_dense(solid, 2 * target_vertices))
    length = _edge_length_for(solid.surface_area(), 1.15 * target_vertices)
    meshset.meshing_isotropic_explicit_remeshing(
        iterations=8, targetlen=pymeshlab.PureValue(length), featuredeg=30.0
    )
    if meshset.current_mesh().vertex_number() > target_vertices:
        _qem(meshset, target_vertices, solid.genus())
    return _current(meshset)


def quad(solid, target_vertices: int, rng: np.random.Generator) -> PolygonMesh:
    """Quad-dominant mesh: the isotropic mesh with triangles paired into quads.

    Parameters
    ----------
    solid : manifold3d.Manifold
    target_vertices : int
    rng : numpy.random.Generator

    Returns
    -------
    PolygonMesh
        Mostly quads, some triangles.
    """
    return pair_triangles(isotropic(solid, target_vertices, rng))


def pair_triangles(mesh: PolygonMesh, max_fold_degrees: float = 8.0) -> PolygonMesh:
    """Merge adjacent triangles into convex, nearly planar quads, best-shaped first.

    A pair is a candidate when the two triangles' normals differ by less than
    ``max_fold_degrees`` and the quad they make is strictly convex. Candidates are
    taken greedily by how far their worst corner is from 90 degrees. (pymeshlab's
    ``meshing_tri_to_quad_by_smart_triangle_pairing`` was tried first: on meshes of
    a few hundred vertices it pairs across sharp edges, and most shapes failed
    validation with non-planar or self-intersecting quads.)

    Parameters
    ----------
    mesh : PolygonMesh
        A closed triangle mesh.
    max_fold_degrees : float

    Returns
    -------
    PolygonMesh
        Quads and the triangles left unpaired.
    """
    tri = mesh.face_indices.reshape(-1, 3)
    v = mesh.vertices
    nbr = _triangle_neighbours(tri)  # (T, 3)
    normals = _triangle_normals(v, tri)
    t, k = np.nonzero(nbr > np.arange(len(tri))[:, None])  # each shared side once
    u = nbr[t, k]
    a, b, c = tri[t, k], tri[t, (k + 1) % 3], tri[t, (k + 2) % 3]
    d = tri[u].sum(axis=1) - a - b  # the corner of u off the shared side (b, a)
    quads = np.stack([a, d, b, c], axis=1)  # (C, 4), counter-clockwise like t
    fold_ok = np.einsum("ij,ij->i", normals[t], normals[u]) > np.cos(np.radians(max_fold_degrees))
    p = v[quads]  # (C, 4, 3)
    e_in = p - np.roll(p, 1, axis=1)
    e_out = np.roll(p, -1, axis=1) - p
    n = (normals[t] + normals[u])[:, None, :]
    lengths = np.linalg.norm(e_in, axis=2) * np.linalg.norm(e_out, axis=2)
    sine = np.einsum("ijk,ijk->ij", np.cross(e_in, e_out), np.broadcast_to(n, e_in.shape))
    sine = sine / np.maximum(lengths * np.linalg.norm(n, axis=2), 1e-300)
    cosine = -np.einsum("ijk,ijk->ij", e_in, e_out) / np.maximum(lengths, 1e-300)
    corner = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))  # (C, 4)
    ok = fold_ok & np.all(sine > 0.1, axis=1)
    score = np.abs(corner - 90.0).max(axis=1)
    used = np.zeros(len(tri), dtype=bool)
    faces: list[list[int]] = []
    for i in np.flatnonzero(ok)[np.argsort(score[ok], kind="stable")]:
        if not used[t[i]] and not used[u[i]]:
            used[t[i]] = used[u[i]] = True
            faces.append([int(x) for x in quads[i]])
    faces.extend([int(x) for x in tri[j]] for j in np.flatnonzero(~used))
    return PolygonMesh.from_faces(v, faces)


# ---------------------------------------------------------------- planar decimation
def _triangle_normals(vertices: np.ndarray, tri: IntArray) -> np.ndarray:
    return unit_rows(triangle_normals(vertices[tri]))  # (T, 3)


def _triangle_neighbours(tri: IntArray) -> IntArray:
    """(T, 3) triangle across side k (from corner k to k+1), -1 where none."""
    n = len(tri)
    origin = tri.reshape(-1)
    target = tri[:, [1, 2, 0]].reshape(-1)
    lookup = {(int(a), int(b)): i for i, (a, b) in enumerate(zip(origin, target, strict=True))}
    out = np.full(3 * n, -1, dtype=np.int64)
    for i, (a, b) in enumerate(zip(origin, target, strict=True)):
        j = lookup.get((int(b), int(a)))
        if j is not None:
            out[i] = j // 3
    return out.reshape(n, 3)


def _grow_regions(
    normals: np.ndarray, area: np.ndarray, nbr: IntArray, cos_limit: float
) -> IntArray:
    """(T,) region label: facets within the angle limit of their region's seed."""
    label = np.full(len(normals), -1, dtype=np.int64)
    region = 0
    for seed in np.argsort(-area, kind="stable"):
        if label[seed] >= 0:
            continue
        label[seed] = region
        stack = [int(seed)]
        while stack:
            t = stack.pop()
            for u in nbr[t]:
                if u >= 0 and label[u] < 0 and normals[u] @ normals[seed] >= cos_limit:
                    label[u] = region
                    stack.append(int(u))
        region += 1
    return label


def _boundary_loop(tri: IntArray, members: IntArray) -> list[int] | None:
    """The single simple boundary loop of a disk-like set of triangles, else None."""
    sides = {}
    for t in members:
        a, b, c = (int(x) for x in tri[t])
        for u, v in ((a, b), (b, c), (c, a)):
            sides[(u, v)] = True
    outgoing: dict[int, int] = {}
    for u, v in sides:
        if (v, u) not in sides:
            if u in outgoing:  # two boundary sides leave one vertex: pinched
                return None
            outgoing[u] = v
    if not outgoing:
        return None
    n_vertices = len({int(x) for x in tri[members].reshape(-1)})
    n_edges = len({(min(u, v), max(u, v)) for u, v in sides})
    if n_vertices - n_edges + len(members) != 1:  # not a disk
        return None
    start = min(outgoing)
    loop = [start]
    while True:
        nxt = outgoing[loop[-1]]
        if nxt == start:
            break
        loop.append(nxt)
        if len(loop) > len(outgoing):
            return None
    return loop if len(loop) == len(outgoing) else None


def _split(vertices: np.ndarray, tri: IntArray, nbr: IntArray, members: IntArray) -> list[IntArray]:
    """Split a region in two by sweeping along its widest axis.

    The first half grows from the extreme facet, always taking the adjacent facet
    furthest back along the axis, so it is connected (and an annulus splits into
    two C shapes, each a disk).
    """
    import heapq

    centres = vertices[tri[members]].mean(axis=1)  # (m, 3)
    axis = int(np.argmax(np.ptp(centres, axis=0)))
    key = dict(zip(members.tolist(), centres[:, axis].tolist(), strict=True))
    start = int(members[np.argmin(centres[:, axis])])
    taken = {start}
    heap = [(key[int(u)], int(u)) for u in nbr[start] if int(u) in key]
    heapq.heapify(heap)
    while heap and len(taken) < len(members) // 2:
        _, t = heapq.heappop(heap)
        if t in taken:
            continue
        taken.add(t)
        for u in nbr[t]:
            u = int(u)
            if u in key and u not in taken:
                heapq.heappush(heap, (key[u], u))
    first = np.array(sorted(taken), dtype=np.int64)
    rest = np.setdiff1d(members, first)
    if rest.size == 0 or first.size == len(members):  # cannot sweep: fall back to a cut
        order = np.argsort(centres[:, axis], kind="stable")
        half = len(members) // 2
        return [members[order[:half]], members[order[half:]]]
    return [first, rest]


def _polygons(
    vertices: np.ndarray, tri: IntArray, nbr: IntArray, label: IntArray
) -> list[list[int]]:
    """One polygon per disk-like region; other regions are split until they are."""
    polygons: list[list[int]] = []
    queue = [np.flatnonzero(label == r) for r in range(int(label.max()) + 1)]
    while queue:
        members = queue.pop()
        if len(members) == 0:
            continue
        loop = _boundary_loop(tri, members) if len(members) > 1 else list(tri[members[0]])
        if loop is not None:
            polygons.append([int(v) for v in loop])
        else:
            queue.extend(_split(vertices, tri, nbr, members))
    return polygons


def _dissolve_two_face_vertices(polygons: list[list[int]]) -> list[list[int]]:
    """Remove vertices that only two faces share (Blender's collinear dissolve)."""
    changed = True
    while changed:
        changed = False
        faces_of: dict[int, list[int]] = {}
        for f, poly in enumerate(polygons):
            for v in poly:
                faces_of.setdefault(v, []).append(f)
        removed: set[int] = set()
        touched: set[int] = set()
        for v, faces in sorted(faces_of.items()):
            if len(faces) != 2 or touched.intersection(faces):
                continue
            if any(len(polygons[f]) <= 3 for f in faces):
                continue
            removed.add(v)
            touched.update(faces)
        if removed:
            polygons = [[v for v in poly if v not in removed] for poly in polygons]
            changed = True
    return polygons


def planar_decimate(mesh: PolygonMesh, angle_degrees: float = 1.0) -> PolygonMesh:
    """Merge nearly coplanar triangles into polygons and dissolve redundant vertices.

    Parameters
    ----------
    mesh : PolygonMesh
        A closed triangle mesh.
    angle_degrees : float
        Facets whose normal is within this angle of their region's seed facet merge.

    Returns
    -------
    PolygonMesh
        A polygon mesh without unreferenced vertices.
    """
    tri = mesh.face_indices.reshape(-1, 3)
    normals = _triangle_normals(mesh.vertices, tri)
    area = np.linalg.norm(
        np.cross(
            mesh.vertices[tri[:, 1]] - mesh.vertices[tri[:, 0]],
            mesh.vertices[tri[:, 2]] - mesh.vertices[tri[:, 0]],
        ),
        axis=1,
    )
    nbr = _triangle_neighbours(tri)
    label = _grow_regions(normals, area, nbr, np.cos(np.radians(angle_degrees)))
    polygons = _dissolve_two_face_vertices(_polygons(mesh.vertices, tri, nbr, label))
    compact, _ = PolygonMesh.from_faces(mesh.vertices, polygons).remove_unreferenced_vertices()
    return compact


def planar(solid, target_vertices: int, rng: np.random.Generator) -> PolygonMesh:
    """Minimal planar-decimated polygon mesh of the solid's exact facets.

    The vertex count is set by the facets of curved primitives (chosen when the
    solid is built, see :func:`segments_for`), not by decimation.

    Parameters
    ----------
    solid : manifold3d.Manifold
    target_vertices : int
        Unused here; the synthesiser picks circular segments from it.
    rng : numpy.random.Generator
        Draws the merge angle limit (0.5 to 3 degrees).

    Returns
    -------
    PolygonMesh
    """
    angle = float(rng.uniform(0.5, 3.0))
    return planar_decimate(solid_to_mesh(solid), angle)


#: Dense vertices per target vertex under the ``farthest`` style's Voronoi diagram.
VORONOI_DENSITY = 40.0
#: Points the ``farthest`` style draws its vertices from (the encoder's 2,048).
FARTHEST_POINTS = 2048


def farthest(solid, target_vertices: int, rng: np.random.Generator) -> PolygonMesh:
    """The pipeline's farthest-point vertices, joined by the restricted Delaunay
    triangulation on the solid's surface.

    Parameters
    ----------
    solid : manifold3d.Manifold
    target_vertices : int
    rng : numpy.random.Generator
        Draws the surface sample and the first farthest point.

    Returns
    -------
    PolygonMesh
        A triangle mesh with the solid's genus.

    Raises
    ------
    ValueError
        The Voronoi regions did not make a surface of the solid's genus (regions that
        are not disks on a thin part): the generator draws another shape.
    """
    length = _edge_length_for(solid.surface_area(), VORONOI_DENSITY * target_vertices)
    dense = solid_to_mesh(solid.refine_to_length(length))
    points, _ = sample_surface(dense, FARTHEST_POINTS, rng)
    pick = farthest_point_sampling(points, target_vertices, seed=int(rng.integers(2**31)),
                                   weights=feature_weights(points, FEATURE_BOOST))
    mesh = restricted_delaunay(dense, points[pick])
    topology = check_topology(mesh)
    if not topology.is_closed_oriented_manifold or topology.genus != solid.genus():
        raise ValueError("the restricted Delaunay mesh is not a surface of the solid's genus")
    return mesh


#: Style name -> function(solid, target_vertices, rng) -> PolygonMesh.
STYLES: dict[str, Callable[..., PolygonMesh]] = {
    "qem": qem,
    "planar": planar,
    "isotropic": isotropic,
    "quad": quad,
    "farthest": farthest,
}


def segments_for(style: str, target_vertices: int, rng: np.random.Generator) -> int:
    """Circular segments of curved primitives for a style and vertex target.

    Parameters
    ----------
    style : str
    target_vertices : int
    rng : numpy.random.Generator

    Returns
    -------
    int
    """
    if style == "planar":  # the facets are the mesh: scale them with the target
        return int(np.clip(np.sqrt(target_vertices) * rng.uniform(0.8, 1.6), 6, 64))
    return 48


def tessellate(style: str, solid, target_vertices: int, rng: np.random.Generator) -> PolygonMesh:
    """Mesh ``solid`` in ``style``.

    Parameters
    ----------
    style : str
        One of :data:`STYLES`.
    solid : manifold3d.Manifold
    target_vertices : int
    rng : numpy.random.Generator

    Returns
    -------
    PolygonMesh
    """
    try:
        function = STYLES[style]
    except KeyError:
        raise ValueError(f"unknown style {style!r}; choose from {', '.join(STYLES)}") from None
    return function(solid, target_vertices, rng)
