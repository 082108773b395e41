"""Polygon faces where the shape is flat (``face_type=polygons``).

The shipped connectivity network makes triangles (its manifest says ``max_sides: 3``).
:func:`merge_coplanar` turns flat regions of its mesh into single polygons by merging
neighbouring faces, flattest edge first, while

* the two faces share exactly one edge and no other vertex (so the merged face visits
  no vertex twice, and no vertex ends up inside a face);
* their normals differ by at most :data:`MAX_ANGLE_DEGREES` (no fold is flattened);
* every corner of the merged face lies within ``tolerance`` of its best-fit plane.

Merging two faces across their one shared edge removes that edge and nothing else: the
mesh stays an oriented edge- and vertex-manifold, closed when it was, with the same
vertices. A merged face that crosses another face while its parts did not (a polygon is
tested, and exported, on a triangulation of its own) is split back into its parts.
Between :data:`FLATTEN_ROUNDS` rounds of merging, each corner of a polygon moves onto
the mean of its polygons' best-fit planes (at most about ``tolerance``), so that the
next round finds flatter neighbours; the moves are kept only if no more faces cross
than before (the exact test) and every polygon stays within the tolerance.
:func:`face_planarity` is the worst corner's distance from its face's best-fit plane,
which the fit report gives.

Before merging, :func:`collapse_flat` collapses the edges whose collapse leaves the
surface where it was (:func:`spacemesh.geometry.simplify.simplify` with the mesh's own
face planes for the cost and a stop at an error), so that flat regions lose the interior
vertices the triangles needed: a finely triangulated box becomes six quads on its eight
corners, and the mesh has fewer vertices than were asked for.

On the dev split's 10 CAD-like parts at the default 200 vertices, merging alone keeps 72%
of the triangles' faces; with the collapses first 53% (33% to 73%; the 20 mm cube: 396
triangles, 129 faces over 98 vertices), every polygon within 0.09% of the diagonal of
its plane and the Chamfer distance to the true shape 1.003 times the triangles'
(docs/GEOMETRY.md, "Polygons").
"""

from __future__ import annotations

import numpy as np

from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.geometry.simplify import simplify
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import edge_keys
from spacemesh.typed import FloatArray, IntArray

#: Largest angle between the normals of two faces that may merge.
MAX_ANGLE_DEGREES = 20.0
#: Rounds of merging with a flattening between them.
FLATTEN_ROUNDS = 3
#: :func:`collapse_flat` makes no collapse whose error (a root mean squared distance from
#: the planes of the faces its vertex stands for) exceeds this many merging tolerances.
COLLAPSE_SHARE = 3.0


def collapse_flat(mesh: PolygonMesh, tolerance: float
                  ) -> tuple[PolygonMesh, dict[str, int | float]]:
    """``mesh`` with the edges collapsed whose collapse leaves the surface where it was,
    so that flat regions lose their interior vertices before :func:`merge_coplanar`.

    The collapses are :func:`spacemesh.geometry.simplify.simplify`'s, the cheapest
    first, with the mesh's own face planes for the cost (no points: the surface where the
    mesh has it) and none whose error exceeds ``(COLLAPSE_SHARE * tolerance)^2``; each
    keeps the mesh an oriented manifold (closed when it was, its boundary fixed), makes
    no face cross another, and keeps the pieces and genus.

    Parameters
    ----------
    mesh : PolygonMesh
        An oriented edge- and vertex-manifold triangle mesh (any other comes back as it
        is).
    tolerance : float
        The merging's planarity tolerance (a distance).

    Returns
    -------
    mesh : PolygonMesh
        Fewer vertices, the survivors in their order, some moved (within the error).
    stats : dict
        ``vertices_collapsed``.
    """
    reduced = simplify(mesh, None, max_error=(COLLAPSE_SHARE * tolerance) ** 2)
    return reduced.mesh, {"vertices_collapsed": mesh.n_vertices - reduced.mesh.n_vertices}


def face_planarity(mesh: PolygonMesh) -> float:
    """The largest distance of a face's corner from the face's best-fit plane (0 for a
    triangle mesh).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    float
        In the mesh's units.
    """
    if mesh.is_triangle_mesh():  # three corners always lie in their plane
        return 0.0
    worst = 0.0
    for face in mesh.faces:
        if len(face) > 3:
            worst = max(worst, _plane_distance(mesh.vertices[face]))
    return worst


def merge_coplanar(mesh: PolygonMesh, tolerance: float
                   ) -> tuple[PolygonMesh, dict[str, int | float]]:
    """``mesh`` with neighbouring near-coplanar faces merged (see the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
        An oriented edge- and vertex-manifold polygon mesh.
    tolerance : float
        Largest distance of a merged face's corner from its best-fit plane.

    Returns
    -------
    mesh : PolygonMesh
        Faces in the order of their first original face.
    stats : dict
        ``faces_merged`` (faces removed by merging), ``vertices_flattened`` (corners
        moved onto their polygons' planes) and ``face_planarity``.
    """
    merged, count = _merged(mesh, tolerance)
    moved = 0
    crossing = int(self_intersecting_faces(mesh).sum())
    for _ in range(FLATTEN_ROUNDS if count else 0):
        flat = _flattened(merged)
        if (int(self_intersecting_faces(flat).sum()) > crossing
                or face_planarity(flat) > tolerance):
            break  # the moves would make faces cross, or bend a polygon: keep what was
        again, more = _merged(flat, tolerance)
        moved = int(np.any(flat.vertices != mesh.vertices, axis=1).sum())
        merged, count = again, count + more
        if more == 0:
            break
    return merged, {"faces_merged": count, "vertices_flattened": moved,
                    "face_planarity": face_planarity(merged)}


def _merged(mesh: PolygonMesh, tolerance: float) -> tuple[PolygonMesh, int]:
    """One round of merging (the module docstring): the mesh and the faces removed."""
    faces = [list(map(int, face)) for face in mesh.faces]
    if len(faces) < 2:
        return mesh, 0
    normals = mesh.face_normals()  # (F, 3)
    pairs, shared = _edge_pairs(mesh)  # (E, 2) faces, (E, 2) vertices a -> b of pairs[:, 0]
    angle = np.einsum("ij,ij->i", normals[pairs[:, 0]], normals[pairs[:, 1]])  # (E,) cos
    keep = angle >= np.cos(np.radians(MAX_ANGLE_DEGREES))
    order = np.flatnonzero(keep)[np.argsort(-angle[keep], kind="stable")]
    group = list(range(len(faces)))  # union-find parent
    loops: dict[int, list[int]] = dict(enumerate(faces))

    def find(f: int) -> int:
        while group[f] != f:
            group[f] = group[group[f]]
            f = group[f]
        return f

    merged = 0
    for e in order:
        first, second = find(int(pairs[e, 0])), find(int(pairs[e, 1]))
        if first == second:
            continue
        a, b = int(shared[e, 0]), int(shared[e, 1])
        loop = _joined(loops[first], loops[second], a, b)
        if loop is None or _plane_distance(mesh.vertices[loop]) > tolerance:
            continue
        group[second] = first
        loops[first] = loop
        del loops[second]
        merged += 1
    if merged == 0:
        return mesh, 0
    members: dict[int, list[int]] = {}
    for f in range(len(faces)):
        members.setdefault(find(f), []).append(f)
    return _uncrossed(mesh, [loops[f] for f in sorted(loops)],
                      [members[f] for f in sorted(loops)])


def _uncrossed(mesh: PolygonMesh, loops: list[list[int]], members: list[list[int]]
               ) -> tuple[PolygonMesh, int]:
    """The merged faces ``loops`` over ``mesh``'s vertices, with every merged face that
    crosses another face while none of its ``members`` (faces of ``mesh``) did split
    back into them, until no such face is left (a polygon is tested on a
    triangulation of its own, which on a fold can differ from its members'); and the
    faces removed."""
    crossed = self_intersecting_faces(mesh)  # (F,) before merging
    while True:
        out = PolygonMesh.from_faces(mesh.vertices, [np.asarray(f, dtype=np.int64)
                                                     for f in loops])
        new = [i for i, hit in enumerate(self_intersecting_faces(out))
               if hit and len(members[i]) > 1 and not crossed[members[i]].any()]
        if not new:
            return out, mesh.n_faces - out.n_faces
        undone = set(new)
        loops = [loop for i, loop in enumerate(loops) if i not in undone] + [
            list(map(int, mesh.faces[f])) for i in new for f in members[i]]
        members = [m for i, m in enumerate(members) if i not in undone] + [
            [f] for i in new for f in members[i]]


def _flattened(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` with every corner of a polygon (more than three corners) moved to the
    mean of its projections onto its polygons' best-fit planes."""
    vertices = mesh.vertices.astype(np.float64)
    total = np.zeros_like(vertices)
    count = np.zeros(len(vertices))
    for face in mesh.faces:
        if len(face) < 4:
            continue
        corners = vertices[face]
        centre = corners.mean(axis=0)
        normal = np.linalg.svd(corners - centre, full_matrices=False)[2][-1]
        np.add.at(total, face, corners - np.outer((corners - centre) @ normal, normal))
        np.add.at(count, face, 1.0)
    moved = count > 0
    vertices[moved] = total[moved] / count[moved, None]
    return mesh.with_vertices(vertices)


def _edge_pairs(mesh: PolygonMesh) -> tuple[IntArray, IntArray]:
    """Faces on both sides of each interior edge, and the edge ``a -> b`` as the first
    face traverses it."""
    halfedges = mesh.halfedges  # (S, 2)
    keys = edge_keys(halfedges, mesh.n_vertices)
    order = np.argsort(keys, kind="stable")
    same = keys[order][1:] == keys[order][:-1]
    first, second = order[:-1][same], order[1:][same]  # corners of the two sides
    face = mesh.face_of_corner
    return (np.stack([face[first], face[second]], axis=1),
            halfedges[first])


def _joined(first: list[int], second: list[int], a: int, b: int) -> list[int] | None:
    """The loop of two faces merged across their edge ``a -> b`` (of ``first``; ``b ->
    a`` of ``second``), or None when they share any other vertex or not that edge."""
    if set(first) & set(second) != {a, b}:
        return None
    i = _edge_at(first, a, b)
    j = _edge_at(second, b, a)
    if i is None or j is None:
        return None
    # first from b around to a, then second's corners strictly between a and b
    path = first[i + 1:] + first[:i + 1]  # starts at b, ends at a
    other = second[j + 1:] + second[:j + 1]  # starts at a, ends at b
    return path + other[1:-1]


def _edge_at(loop: list[int], a: int, b: int) -> int | None:
    """The index of ``a`` in ``loop`` when ``b`` follows it, else None."""
    for i, v in enumerate(loop):
        if v == a and loop[(i + 1) % len(loop)] == b:
            return i
    return None


def _plane_distance(corners: FloatArray) -> float:
    """The largest distance of ``corners`` (K, 3) from their best-fit plane."""
    centred = corners - corners.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    return float(np.abs(centred @ vt[-1]).max())
