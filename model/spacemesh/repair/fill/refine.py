"""Refining a hole's patch to the density of the surface around it (Liepa, "Filling
holes in meshes", SGP 2003, Sec. 4).

The patch's large polygons are fanned from their centroid, every interior edge of its
triangles longer than :data:`SPLIT_RATIO` times the target length (the mean length of
the hole's boundary edges) is split at its midpoint, both triangles on it in two, then
its interior edges are flipped towards Delaunay triangles (:func:`refine_patch`); quads,
pentagons and the hole's boundary edges are never split.

numpy only; no face outside the patch changes.
"""

from __future__ import annotations

import math

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset, faces_touching
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: An interior patch edge longer than this times the target length is split.
SPLIT_RATIO = math.sqrt(2.0)
#: Most vertices a refinement adds, as a multiple of the patch's area over that of an
#: equilateral triangle of the target edge (bounds the work).
MAX_DENSITY = 2.0
#: Most rounds of splits (each splits every long edge whose triangles are untouched).
MAX_ROUNDS = 24
#: Patch polygons with at least this many corners (the splice's last resort, one
#: polygon over a loop the model could not fill) are fanned from their centroid first.
FAN_CORNERS = 6
#: Sweeps of Delaunay flips after the splits.
FLIP_SWEEPS = 4


def _edge_key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


def _opposite_angle(p: FloatArray, a: int, b: int, c: int) -> float:
    """The angle at ``c`` of the triangle ``a b c``."""
    u, v = p[a] - p[c], p[b] - p[c]
    cos = float(u @ v) / max(float(np.linalg.norm(u) * np.linalg.norm(v)), 1e-300)
    return math.acos(min(1.0, max(-1.0, cos)))


class _Triangles:
    """The patch's triangles as a mutable list with an edge -> triangles map."""

    def __init__(self, triangles: list[list[int]], taken: set[tuple[int, int]]) -> None:
        self.taken = taken  # edges of the faces outside the patch (never made by a flip)
        tris = [list(t) for t in triangles]
        self.tris: list[list[int] | None] = list(tris)
        self.edges: dict[tuple[int, int], list[int]] = {}
        for t, tri in enumerate(tris):
            self._link(t, tri)

    def _link(self, t: int, tri: list[int]) -> None:
        for k in range(3):
            self.edges.setdefault(_edge_key(tri[k], tri[(k + 1) % 3]), []).append(t)

    def _unlink(self, t: int) -> None:
        tri = self.tris[t]
        assert tri is not None
        for k in range(3):
            key = _edge_key(tri[k], tri[(k + 1) % 3])
            self.edges[key].remove(t)
            if not self.edges[key]:
                del self.edges[key]
        self.tris[t] = None

    def replace(self, old: list[int], new: list[list[int]]) -> None:
        for t in old:
            self._unlink(t)
        for tri in new:
            self.tris.append(tri)
            self._link(len(self.tris) - 1, tri)

    def interior(self) -> list[tuple[tuple[int, int], int, int]]:
        """Edges with a patch triangle on each side: (edge, triangle, triangle)."""
        return [(e, ts[0], ts[1]) for e, ts in self.edges.items() if len(ts) == 2]

    @staticmethod
    def apex(tri: list[int], a: int, b: int) -> tuple[int, bool]:
        """The corner of ``tri`` off the edge ``a b``, and whether ``tri`` runs ``a -> b``."""
        k = tri.index(a)
        forward = tri[(k + 1) % 3] == b
        return tri[(k + 2) % 3] if forward else tri[(k + 1) % 3], forward

    def alive(self) -> list[list[int]]:
        return [t for t in self.tris if t is not None]


class _Positions:
    """The mesh's vertex positions followed by the ones the refinement adds: appending
    costs nothing and :meth:`array` copies the mesh's positions once per call, never
    a Python list of every vertex."""

    def __init__(self, base: FloatArray) -> None:
        self.base = np.asarray(base, dtype=np.float64)
        self.added: list[FloatArray] = []

    def __len__(self) -> int:
        return len(self.base) + len(self.added)

    def append(self, position: FloatArray) -> None:
        self.added.append(np.asarray(position, dtype=np.float64))

    def array(self) -> FloatArray:
        """(V + added, 3) every position."""
        if not self.added:
            return self.base.copy()
        return np.concatenate([self.base, np.stack(self.added)])


def _split_pass(tris: _Triangles, positions: _Positions, limit: float,
                budget: int) -> int:
    """Split the interior edges longer than ``limit`` (longest first); returns the
    vertices added."""
    p = positions.array()
    long = [(float(np.linalg.norm(p[e[0]] - p[e[1]])), e) for e, _, _ in tris.interior()]
    long = sorted((x for x in long if x[0] > limit), reverse=True)
    touched: set[int] = set()
    added = 0
    for _, (a, b) in long:
        if added >= budget:
            break
        ts = tris.edges.get((a, b), [])
        if len(ts) != 2 or touched & set(ts):
            continue
        tri_a, tri_b = tris.tris[ts[0]], tris.tris[ts[1]]
        assert tri_a is not None and tri_b is not None
        if not _Triangles.apex(tri_a, a, b)[1]:
            tri_a, tri_b = tri_b, tri_a
        c, _ = _Triangles.apex(tri_a, a, b)  # a -> b -> c
        d, _ = _Triangles.apex(tri_b, a, b)  # b -> a -> d
        m = len(positions)
        positions.append((p[a] + p[b]) / 2.0)
        touched.update(ts)
        tris.replace(list(ts), [[a, m, c], [m, b, c], [b, m, d], [m, a, d]])
        touched.update(range(len(tris.tris) - 4, len(tris.tris)))
        added += 1
    return added


def _flip_pass(tris: _Triangles, p: FloatArray) -> int:
    """Flip interior edges whose opposite angles sum beyond pi (Delaunay); returns the
    flips made."""
    flips = 0
    for (a, b), _, _ in tris.interior():
        ts = tris.edges.get((a, b), [])
        if len(ts) != 2:
            continue
        tri_a, tri_b = tris.tris[ts[0]], tris.tris[ts[1]]
        assert tri_a is not None and tri_b is not None
        if not _Triangles.apex(tri_a, a, b)[1]:
            tri_a, tri_b = tri_b, tri_a
        c, _ = _Triangles.apex(tri_a, a, b)
        d, _ = _Triangles.apex(tri_b, a, b)
        if c == d or _edge_key(c, d) in tris.edges or _edge_key(c, d) in tris.taken:
            continue
        if _opposite_angle(p, a, b, c) + _opposite_angle(p, a, b, d) <= math.pi + 1e-9:
            continue
        tris.replace(list(ts), [[a, d, c], [d, b, c]])
        flips += 1
    return flips


def refine_patch(mesh: PolygonMesh, patch: BoolArray, target: float
                 ) -> tuple[PolygonMesh, IntArray]:
    """Split the long interior edges of the patch's triangles and flip towards Delaunay.

    Parameters
    ----------
    mesh : PolygonMesh
    patch : (F,) bool
        The patch's faces; only its triangles are refined, and only along edges with a
        patch triangle on both sides (its boundary and its quads and pentagons stay as
        they are); its polygons of :data:`FAN_CORNERS` or more corners are first fanned
        from a new vertex at their centroid.
    target : float
        The edge length aimed at; edges longer than :data:`SPLIT_RATIO` times it are split.

    Returns
    -------
    mesh : PolygonMesh
        The input's vertices then the new ones (centroids, midpoints); the faces not
        refined in their order, then the patch's triangles.
    face_source : (F',) int64
        The input face of each face (-1 for the refined triangles).
    """
    sizes = mesh.face_sizes
    tri_faces = np.flatnonzero(patch & ((sizes == 3) | (sizes >= FAN_CORNERS)))
    if len(tri_faces) == 0 or not target > 0:
        return mesh, np.arange(mesh.n_faces)
    positions = _Positions(mesh.vertices)
    triangles: list[list[int]] = []
    for f in tri_faces:
        corners = mesh.face_indices[mesh.face_offsets[f]:mesh.face_offsets[f + 1]].tolist()
        if len(corners) == 3:
            triangles.append(corners)
            continue
        centre = len(positions)  # a large polygon becomes a fan from its centroid
        positions.append(mesh.vertices[corners].mean(axis=0))
        triangles += [[a, b, centre] for a, b in zip(corners, np.roll(corners, -1).tolist(),
                                                     strict=True)]
    outside = np.ones(mesh.n_faces, dtype=bool)
    outside[tri_faces] = False
    # a flip can only make an edge between two corners of the patch's triangles, so only
    # the outside faces at those corners can hold an edge it must not make: the others
    # are never looked at (the whole mesh's edges took seconds on 300,000 faces)
    corners_of_patch = np.zeros(mesh.n_vertices, dtype=bool)
    corners_of_patch[mesh.face_indices[~outside[mesh.face_of_corner]]] = True
    near = outside & faces_touching(mesh, corners_of_patch)
    tris = _Triangles(triangles, {_edge_key(a, b) for a, b in
                                  faces_subset(mesh, near).edges.tolist()})
    corners = positions.array()[np.asarray(triangles)]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1).sum()
    budget = int(MAX_DENSITY * area / (math.sqrt(3) / 4 * target**2)) + 1
    added = 0
    for _ in range(MAX_ROUNDS):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        if added >= budget:
            break
        step = _split_pass(tris, positions, SPLIT_RATIO * target, budget - added)
        if step == 0:
            break
        added += step
        _flip_pass(tris, positions.array())
    if added == 0 and len(positions) == mesh.n_vertices:
        return mesh, np.arange(mesh.n_faces)
    p = positions.array()
    for _ in range(FLIP_SWEEPS):
        checkpoint()
        if _flip_pass(tris, p) == 0:
            break
    keep = np.ones(mesh.n_faces, dtype=bool)
    keep[tri_faces] = False
    kept = np.flatnonzero(keep)
    new = np.asarray(tris.alive(), dtype=np.int64)
    kept_mesh = faces_subset(mesh, keep)
    indices = np.concatenate([kept_mesh.face_indices, new.reshape(-1)])
    offsets = np.concatenate([kept_mesh.face_offsets,
                              kept_mesh.face_offsets[-1] + 3 * np.arange(1, len(new) + 1)])
    out = PolygonMesh(p, indices, offsets.astype(np.int64))
    source = np.concatenate([kept, np.full(len(new), -1)]).astype(np.int64)
    return out, source
