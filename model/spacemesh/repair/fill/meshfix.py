"""MeshFix's own hole fill, restricted to one hole: the fallback an automatic region of
holes may take instead of its model-and-fairing patch (docs/REPAIR.md).

MeshFix (Attene 2010, through ``pymeshfix``'s ``PyTMesh.fill_small_boundaries`` with
``refine=True``) triangulates a hole, refines the triangulation and fairs it. Here it is
run on the faces around the hole only (:func:`meshfix_fill`), and only its new faces
that close the hole's loops are taken, so every other face stays as it was. The
automatic regions take it where the fairing would span the hole flat
(:attr:`spacemesh.repair.fill.policy.FillPolicy.meshfix_fairings`) and where the probe
holes prefer it (:mod:`spacemesh.repair.fill.probe`).

``pymeshfix`` is optional (the ``geometry`` extra): without it :func:`meshfix_fill` returns None
and the fairing's patch is kept.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    component_labels,
    faces_subset,
    faces_touching,
    triangulate_faces,
    vertices_of,
)
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Rings of faces around a hole handed to MeshFix.
RINGS = 5


def faces_around(mesh: PolygonMesh, vertices: BoolArray, rings: int = RINGS) -> BoolArray:
    """(F,) the faces within ``rings`` rings of faces of the ``vertices`` ((V,) bool)."""

    marked = vertices.copy()
    for _ in range(rings - 1):
        marked |= vertices_of(mesh, faces_touching(mesh, marked))
    return faces_touching(mesh, marked)


def _run_meshfix(mesh: PolygonMesh, faces: BoolArray
                 ) -> tuple[IntArray, FloatArray, IntArray] | None:
    """MeshFix's fill of every boundary of the triangulated ``faces`` of ``mesh``.

    Returns the new triangles (T, 3) over ``mesh``'s vertices then new ones (``n_vertices
    + k``), the new vertices' positions (K, 3), and ``used`` (the mesh vertices handed
    over); None without ``pymeshfix`` or when its old vertices cannot be found again
    (moved, or two at one position)."""
    try:
        import pymeshfix
    except ImportError:  # the geometry extra is not installed
        return None

    triangles, _ = triangulate_faces(faces_subset(mesh, faces))  # (T, 3) mesh vertex ids
    if len(triangles) == 0:
        return None
    used, local = np.unique(triangles, return_inverse=True)
    local = local.reshape(-1, 3)
    fixer = pymeshfix.PyTMesh()
    fixer.set_quiet(True)
    fixer.load_array(np.ascontiguousarray(mesh.vertices[used], dtype=np.float64),
                     np.ascontiguousarray(local, dtype=np.int32))
    fixer.fill_small_boundaries(nbe=0, refine=True)
    points, out = fixer.return_arrays()
    points = np.asarray(points, dtype=np.float64)
    out = np.asarray(out, dtype=np.int64).reshape(-1, 3)
    # MeshFix reorders the vertices: the old ones are found again by their positions
    where = {tuple(p): int(v) for v, p in zip(used.tolist(), mesh.vertices[used].tolist(),
                                               strict=True)}
    if len(where) != len(used):
        return None  # two vertices at one position: no way to tell them apart
    ids = np.full(len(points), -1, dtype=np.int64)
    for k, p in enumerate(points.tolist()):
        ids[k] = where.get(tuple(p), -1)
    new_points = np.flatnonzero(ids < 0)
    if len(points) - len(new_points) != len(used):
        return None
    ids[new_points] = mesh.n_vertices + np.arange(len(new_points))
    mapped = ids[out]
    had = {tuple(sorted(t)) for t in triangles.tolist()}
    new = mapped[[tuple(sorted(t)) not in had for t in mapped.tolist()]]
    return new, points[new_points], used


def meshfix_fill(mesh: PolygonMesh, loops: list[IntArray]
                 ) -> tuple[FloatArray, IntArray] | None:
    """MeshFix's patch closing exactly the ``loops`` of ``mesh`` (their faces around).

    Parameters
    ----------
    mesh : PolygonMesh
        The mesh with the hole open.
    loops : list of (L,) int64
        The hole's loops, in the direction a filling face traverses them.

    Returns
    -------
    (positions, triangles) or None
        The new vertices' positions (K, 3) and the patch's triangles (T, 3) over
        ``mesh``'s vertices then the new ones; None without ``pymeshfix``, or when its
        patch does not close exactly these loops as an oriented manifold.
    """
    on_loop = np.zeros(mesh.n_vertices, dtype=bool)
    for loop in loops:
        on_loop[loop] = True
    fixed = _run_meshfix(mesh, faces_around(mesh, on_loop))
    if fixed is None:
        return None
    triangles, points, _ = fixed
    if len(triangles) == 0:
        return None
    # the components of new triangles (joined by shared vertices) touching the loops
    n = mesh.n_vertices + len(points)
    rows = np.repeat(np.arange(len(triangles)), 3)  # (3T,) nodes: triangles, then vertices
    _, label = component_labels(len(triangles) + n,
                                np.stack([rows, len(triangles) + triangles.reshape(-1)], axis=1))
    touching = np.unique(label[len(triangles) + np.flatnonzero(on_loop)])
    patch = triangles[np.isin(label[: len(triangles)], touching)]
    # its border must be the loops, in their direction, and no inner edge an old one
    halfedges = np.stack([patch, np.roll(patch, -1, axis=1)], axis=2).reshape(-1, 2)
    keys = set(map(tuple, halfedges.tolist()))
    if len(keys) != len(halfedges):
        return None
    border = {(a, b) for a, b in keys if (b, a) not in keys}
    wanted = {(int(a), int(b)) for loop in loops for a, b in zip(loop, np.roll(loop, -1),
                                                                   strict=True)}
    if border != wanted:
        return None
    old = {tuple(sorted(e)) for e in mesh.edges.tolist()}
    inner = {tuple(sorted(e)) for e in keys if e not in border}
    if any(a < mesh.n_vertices and b < mesh.n_vertices and (a, b) in old for a, b in inner):
        return None
    new_ids = np.unique(patch[patch >= mesh.n_vertices])
    remap = np.full(n, -1, dtype=np.int64)
    remap[: mesh.n_vertices] = np.arange(mesh.n_vertices)
    remap[new_ids] = mesh.n_vertices + np.arange(len(new_ids))
    return points[new_ids - mesh.n_vertices], remap[patch]
