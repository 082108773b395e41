"""Cutting the region out of a mesh: growth, boundary loops, and the defects left outside.

Rules (see docs/REPAIR.md):

1. The region is a set of faces. Its faces are removed; vertices used only by removed
   faces are removed with them. Every other face is *kept* and comes back unchanged.
2. The region grows until no hole is pinched: a kept vertex that touches a removed face
   must have a single fan of kept faces with a single gap (one incoming and one outgoing
   hole halfedge). A vertex that breaks this loses all its faces to the region, and the
   test repeats. Growing to the whole mesh is a ``whole-mesh-region`` error.
3. The kept faces must form an oriented manifold whose only boundary is the hole: a
   kept edge with one face is part of the hole when both its vertices are vertices of
   region faces (so a region around an existing hole covers it). Any other open
   boundary edge, non-manifold or
   misoriented edge, pinched vertex, or face with fewer than three distinct vertices
   among the kept faces is a defect outside the region (``defects-outside-region``,
   with the defects listed, and the count of vertices that share their exact position
   with another: a mesh split at seams, which ``weld=True`` merges first, see
   :mod:`spacemesh.repair.weld`). Defects inside the region are simply removed with it.
4. The hole's boundary is a set of simple loops. A loop lists its vertices in the order
   the filling faces traverse them: the hole halfedge ``i -> loop_next[i]`` is the twin
   of the kept boundary halfedge ``loop_next[i] -> i``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_touching, vertices_of
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.repair.region import (
    DEFECTS_OUTSIDE_REGION,
    WHOLE_MESH_REGION,
    Region,
    RegionError,
    parse_region,
    region_faces,
)
from spacemesh.repair.weld import coincident_vertices
from spacemesh.typed import BoolArray, IntArray

#: Indices listed per defect kind in a ``defects-outside-region`` error.
MAX_LISTED = 20


def _hole_halfedges(sub: FaceSubset, touched: BoolArray) -> IntArray:
    """(H, 2) hole halfedges: twins of the kept one-sided edges between region vertices."""
    one_sided = sub.edge_count[sub.edge] == 1
    he = sub.halfedges[one_sided]
    on_hole = touched[he[:, 0]] & touched[he[:, 1]]
    return he[on_hole][:, ::-1]


# ---------------------------------------------------------------------- growth
def grow_region(mesh: PolygonMesh, region: BoolArray) -> BoolArray:
    """Grow ``region`` until every kept vertex on its border has a single-gap fan.

    Parameters
    ----------
    mesh : PolygonMesh
    region : (F,) bool

    Returns
    -------
    (F,) bool
        The grown region (a superset of ``region``; possibly every face).
    """
    region = np.asarray(region, dtype=bool).copy()
    while True:  # each round adds at least one face, so this ends
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        touched = vertices_of(mesh, region)
        local = np.flatnonzero(faces_touching(mesh, touched) & ~region)
        if local.size == 0:
            return region
        sub = FaceSubset.of(mesh, local)
        fans = sub.fan_counts(mesh.n_vertices)
        hole = _hole_halfedges(sub, touched)
        out_count = np.bincount(hole[:, 0], minlength=mesh.n_vertices)
        in_count = np.bincount(hole[:, 1], minlength=mesh.n_vertices)
        bad = touched & ((fans > 1) | (out_count > 1) | (in_count > 1))
        if not bad.any():
            return region
        region |= faces_touching(mesh, bad)
        if region.all():
            return region


# ---------------------------------------------------------------------- defects
def _listed(values: IntArray) -> list[int]:
    return [int(v) for v in np.unique(values)[:MAX_LISTED]]


def outside_defects(mesh: PolygonMesh, region: BoolArray,
                    tolerated: BoolArray | None = None) -> list[dict]:
    """The topological defects of the kept faces that the region does not cover.

    Parameters
    ----------
    mesh : PolygonMesh
    region : (F,) bool
        Faces removed.
    tolerated : (V,) bool, optional
        Vertices whose defects are left alone (those of the other regions of an
        automatic repair, repaired by passes of their own): an edge with both ends, a
        vertex, or a face with a corner there is not reported.

    Returns
    -------
    list of dict
        One entry per kind present: ``kind`` (``open-boundary``,
        ``non-manifold-edges``, ``misoriented-edges``, ``pinched-vertices``,
        ``degenerate-faces``), ``count``, ``description``, and the first
        :data:`MAX_LISTED` offending ``vertices`` or ``faces`` (original indices).
        Empty when the kept faces are an oriented manifold bounded by the hole only.
    """
    kept = np.flatnonzero(~region)
    sub = FaceSubset.of(mesh, kept)
    he, count = sub.halfedges, sub.edge_count[sub.edge]
    defects: list[dict] = []
    ok = np.zeros(mesh.n_vertices, dtype=bool) if tolerated is None else tolerated
    he_ok = ok[he[:, 0]] & ok[he[:, 1]]

    n = max(mesh.n_vertices, 1)
    sizes = mesh.face_sizes[kept]
    fv = np.sort(sub.face * n + he[:, 0])
    repeated = np.unique(fv[1:][fv[1:] == fv[:-1]] // n)
    degenerate = np.union1d(kept[sizes < 3], repeated)
    if tolerated is not None and degenerate.size:
        near = np.zeros(mesh.n_faces, dtype=bool)
        near[mesh.face_of_corner[tolerated[mesh.face_indices]]] = True
        degenerate = degenerate[~near[degenerate]]
    if degenerate.size:
        defects.append({"kind": "degenerate-faces", "count": int(degenerate.size),
                        "description": "degenerate faces (fewer than three distinct vertices)",
                        "faces": _listed(degenerate)})

    touched = vertices_of(mesh, region)
    open_side = (count == 1) & ~(touched[he[:, 0]] & touched[he[:, 1]]) & ~he_ok
    if open_side.any():
        defects.append({"kind": "open-boundary", "count": int(open_side.sum()),
                        "description": "open boundary edges",
                        "vertices": _listed(he[open_side].reshape(-1))})
    nonmanifold = (count > 2) & ~he_ok
    if nonmanifold.any():
        defects.append({"kind": "non-manifold-edges",
                        "count": int(np.unique(sub.edge[nonmanifold]).size),
                        "description": "non-manifold edges (more than two faces)",
                        "vertices": _listed(he[nonmanifold].reshape(-1))})
    misoriented = (count == 2) & (sub.twin < 0) & ~he_ok
    if misoriented.any():
        defects.append({"kind": "misoriented-edges",
                        "count": int(np.unique(sub.edge[misoriented]).size),
                        "description": "misoriented edges (two faces traverse them the same way)",
                        "vertices": _listed(he[misoriented].reshape(-1))})
    fans = sub.fan_counts(mesh.n_vertices)
    pinched = np.flatnonzero((fans > 1) & ~ok)
    if pinched.size:
        defects.append({"kind": "pinched-vertices", "count": int(pinched.size),
                        "description": "pinched vertices (more than one fan of faces)",
                        "vertices": _listed(pinched)})
    return defects


def defect_vertices(mesh: PolygonMesh) -> BoolArray:
    """(V,) every vertex on a topological defect of ``mesh``.

    The vertices of open boundary, non-manifold and misoriented edges, pinched
    vertices, and the vertices of degenerate faces: a region that covers them all
    (e.g. ``{"vertices": np.flatnonzero(defect_vertices(mesh))}``) makes the mesh
    repairable.
    """
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    he, count = sub.halfedges, sub.edge_count[sub.edge]
    bad_side = (count == 1) | (count > 2) | ((count == 2) & (sub.twin < 0))
    marked = np.zeros(mesh.n_vertices, dtype=bool)
    marked[he[bad_side].reshape(-1)] = True
    marked |= sub.fan_counts(mesh.n_vertices) > 1
    n = max(mesh.n_vertices, 1)
    fv = np.sort(sub.face * n + he[:, 0])
    repeated = np.unique(fv[1:][fv[1:] == fv[:-1]] // n)
    degenerate = np.union1d(np.flatnonzero(mesh.face_sizes < 3), repeated)
    corner_bad = np.isin(mesh.face_of_corner, degenerate)
    marked[mesh.face_indices[corner_bad]] = True
    return marked


def defects_message(defects: list[dict], coincident: int = 0) -> str:
    """One sentence naming the defects outside the region.

    Parameters
    ----------
    defects : list of dict
        From :func:`outside_defects`.
    coincident : int
        Vertices at exactly the position of another vertex
        (:func:`spacemesh.repair.weld.coincident_vertices`); when positive, the sentence
        ends with the hint that ``weld=true`` merges them.
    """
    parts = []
    for d in defects:
        where = d.get("vertices", d.get("faces", []))
        noun = "vertices" if "vertices" in d else "faces"
        parts.append(f"{d['count']} {d['description']} (e.g. {noun} "
                     f"{', '.join(str(i) for i in where[:5])})")
    message = ("the mesh has defects outside the region; extend the region to cover them: "
               + "; ".join(parts))
    if coincident > 0:
        message += (f". {coincident} vertices share their exact position with another "
                    "vertex (a mesh split at UV seams or hard edges looks open there): "
                    "the repair option weld=true (--weld) merges them first")
    return message


# ---------------------------------------------------------------------- the cut
@dataclass(frozen=True)
class Cut:
    """A mesh with its region cut out.

    Attributes
    ----------
    mesh : PolygonMesh
        The mesh cut: the repair's input, or its weld (``weld=True``).
    region : (F,) bool
        Faces removed (after growth).
    requested : (F,) bool
        Faces the region selected before growth.
    boundary : (B,) int64
        Vertices on the hole's boundary (original indices, ascending).
    loop_next, loop_prev : (B,) int64
        Position in ``boundary`` of the next / previous vertex along the hole, in the
        direction the filling faces traverse it.
    removed_vertices : (R,) int64
        Vertices used only by removed faces (they are not in the output).
    loops : list of (L,) int64
        Each hole loop as original vertex indices in traversal order.
    """

    mesh: PolygonMesh
    region: BoolArray
    requested: BoolArray
    boundary: IntArray
    loop_next: IntArray
    loop_prev: IntArray
    removed_vertices: IntArray
    loops: list[IntArray] = field(default_factory=list)

    @property
    def kept_faces(self) -> IntArray:
        """(F_k,) original indices of the kept faces."""
        return np.flatnonzero(~self.region)

    @property
    def n_grown(self) -> int:
        """Faces the growth added to the requested region."""
        return int(self.region.sum() - self.requested.sum())

    def kept_vertex_mask(self) -> BoolArray:
        """(V,) vertices that stay (all but ``removed_vertices``)."""
        keep = np.ones(self.mesh.n_vertices, dtype=bool)
        keep[self.removed_vertices] = False
        return keep


def boundary_loops(hole: IntArray) -> tuple[IntArray, IntArray, IntArray, list[IntArray]]:
    """Loops of hole halfedges that form a set of disjoint simple cycles.

    Parameters
    ----------
    hole : (H, 2) int64
        Hole halfedges; every vertex must have exactly one outgoing and one incoming.

    Returns
    -------
    boundary : (B,) int64
    loop_next, loop_prev : (B,) int64
        Positions in ``boundary``.
    loops : list of (L,) int64
    """
    boundary = np.unique(hole.reshape(-1))
    src = np.searchsorted(boundary, hole[:, 0])
    dst = np.searchsorted(boundary, hole[:, 1])
    if (np.bincount(src, minlength=len(boundary)) != 1).any() or (
        np.bincount(dst, minlength=len(boundary)) != 1
    ).any():
        raise ValueError("hole halfedges do not form disjoint simple loops")
    loop_next = np.full(len(boundary), -1, dtype=np.int64)
    loop_next[src] = dst
    loop_prev = np.full(len(boundary), -1, dtype=np.int64)
    loop_prev[dst] = src
    seen = np.zeros(len(boundary), dtype=bool)
    loops = []
    for start in range(len(boundary)):
        if seen[start]:
            continue
        cycle = []
        i = start
        while not seen[i]:
            seen[i] = True
            cycle.append(i)
            i = int(loop_next[i])
        loops.append(boundary[np.asarray(cycle, dtype=np.int64)])
    return boundary, loop_next, loop_prev, loops


def cut_region(mesh: PolygonMesh, region: Region | Mapping[str, Any] | BoolArray,
               tolerated: BoolArray | None = None) -> Cut:
    """Cut a region out of ``mesh`` (rules in the module docstring).

    Parameters
    ----------
    mesh : PolygonMesh
    region : Region, dict or (F,) bool
        A region, its JSON form, or a face mask.
    tolerated : (V,) bool, optional
        Vertices whose defects are left alone (:func:`outside_defects`).

    Returns
    -------
    Cut

    Raises
    ------
    RegionError
        ``invalid-region``, ``empty-region``, ``whole-mesh-region`` or
        ``defects-outside-region`` (with ``details["defects"]``, and
        ``details["coincident_vertices"]``: vertices at exactly the position of another,
        which ``weld=True`` would merge; the message says so when there are any).
    """
    if isinstance(region, np.ndarray) and region.dtype == bool:
        if region.shape != (mesh.n_faces,):
            raise ValueError(f"a face mask must have shape ({mesh.n_faces},)")
        requested = region_faces(mesh, Region.from_faces(np.flatnonzero(region)))
    else:  # a region or its JSON form (anything else is invalid-region)
        requested = region_faces(mesh, parse_region(region))
    grown = grow_region(mesh, requested)
    if grown.all():
        raise RegionError(WHOLE_MESH_REGION, "the region grows to the whole mesh: every kept "
                          "vertex next to it would be pinched; mark a smaller region")
    defects = outside_defects(mesh, grown, tolerated)
    if defects:
        coincident = coincident_vertices(mesh)
        raise RegionError(DEFECTS_OUTSIDE_REGION, defects_message(defects, coincident),
                          {"defects": defects, "coincident_vertices": coincident})
    touched = vertices_of(mesh, grown)
    local = np.flatnonzero(faces_touching(mesh, touched) & ~grown)
    hole = _hole_halfedges(FaceSubset.of(mesh, local), touched)
    boundary, loop_next, loop_prev, loops = boundary_loops(hole)
    kept_used = np.zeros(mesh.n_vertices, dtype=bool)
    kept_used[mesh.face_indices[~grown[mesh.face_of_corner]]] = True
    removed = np.flatnonzero(touched & ~kept_used)
    return Cut(mesh, grown, requested, boundary, loop_next, loop_prev, removed, loops)
