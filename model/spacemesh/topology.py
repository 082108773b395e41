"""Topological checks of polygon meshes: manifoldness, orientation, closedness, genus.

Everything here depends on connectivity only; geometric checks (self-intersections,
degenerate areas, outward orientation) live in :mod:`spacemesh.data.validate`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels, edge_keys, weld
from spacemesh.typed import BoolArray, IntArray


@dataclass(frozen=True)
class TopologyReport:
    """Counts of topological defects of a polygon mesh (all zero for a closed manifold)."""

    n_vertices: int
    n_faces: int
    n_edges: int
    n_small_faces: int  # faces with fewer than 3 sides
    n_repeated_vertex_faces: int  # faces that visit a vertex twice
    n_boundary_edges: int  # edges with one incident face
    n_nonmanifold_edges: int  # edges with more than two incident faces
    n_misoriented_edges: int  # edges whose two faces traverse them the same way
    n_nonmanifold_vertices: int  # vertices whose faces form more than one fan
    n_unreferenced_vertices: int
    n_components: int  # edge-connected components of faces
    euler_characteristic: int

    @property
    def is_edge_manifold(self) -> bool:
        """Every edge has at most two faces."""
        return self.n_nonmanifold_edges == 0

    @property
    def is_closed(self) -> bool:
        """No boundary edges."""
        return self.n_boundary_edges == 0

    @property
    def is_oriented(self) -> bool:
        """Neighbouring faces traverse shared edges in opposite directions."""
        return self.n_misoriented_edges == 0

    @property
    def is_manifold(self) -> bool:
        """Edge- and vertex-manifold, with well-formed faces."""
        return (
            self.n_small_faces == 0
            and self.n_repeated_vertex_faces == 0
            and self.n_nonmanifold_edges == 0
            and self.n_nonmanifold_vertices == 0
        )

    @property
    def is_closed_oriented_manifold(self) -> bool:
        """Closed, manifold and consistently oriented: what SpaceMesh can encode."""
        return self.is_manifold and self.is_closed and self.is_oriented and self.n_faces > 0

    def is_valid(self, open_surface: bool = False) -> bool:
        """What every output must be: edge- and vertex-manifold, oriented, with faces,
        and closed unless it is an open surface (``surface=open``: boundary allowed).

        Parameters
        ----------
        open_surface : bool
            Whether boundary edges are allowed.

        Returns
        -------
        bool
        """
        return (self.is_manifold and self.is_oriented and self.n_faces > 0
                and (open_surface or self.is_closed))

    @property
    def genus(self) -> int | None:
        """Genus summed over components, for closed oriented manifolds (else None)."""
        if not self.is_closed_oriented_manifold:
            return None
        return (2 * self.n_components - self.euler_characteristic) // 2

    def defects(self, open_surface: bool = False) -> list[str]:
        """Human-readable list of what is wrong (empty for a closed oriented manifold;
        with ``open_surface``, boundary edges are not wrong)."""
        names = {
            "n_small_faces": "faces with fewer than 3 sides",
            "n_repeated_vertex_faces": "faces that repeat a vertex",
            "n_boundary_edges": "boundary edges (the mesh is open)",
            "n_nonmanifold_edges": "non-manifold edges (more than two faces)",
            "n_misoriented_edges": "inconsistently oriented edges",
            "n_nonmanifold_vertices": "non-manifold vertices (pinched fans)",
        }
        if open_surface:
            del names["n_boundary_edges"]
        out = [f"{getattr(self, key)} {text}" for key, text in names.items() if getattr(self, key)]
        if self.n_faces == 0:
            out.append("no faces")
        return out

    def to_dict(self) -> dict:
        """Plain dict with the counts and the derived flags."""
        data = asdict(self)
        data.update(
            is_manifold=self.is_manifold,
            is_closed=self.is_closed,
            is_oriented=self.is_oriented,
            genus=self.genus,
        )
        return data


def count_vertex_fans(mesh: PolygonMesh) -> IntArray:
    """(V,) number of edge-connected fans of faces around each vertex (0 if unused).

    Corners (face, vertex) at the same vertex are joined when their faces share an
    edge incident to that vertex through exactly two face sides (:func:`corner_fans`).
    """
    fan = corner_fans(mesh)  # (S,)
    if len(fan) == 0:
        return np.zeros(mesh.n_vertices, dtype=np.int64)
    fan_vertex = np.zeros(int(fan.max()) + 1, dtype=np.int64)
    fan_vertex[fan] = mesh.face_indices
    return np.bincount(fan_vertex, minlength=mesh.n_vertices).astype(np.int64)


def corner_fans(mesh: PolygonMesh) -> IntArray:
    """(S,) the fan of each corner: corners at one vertex whose faces are joined through
    edges at that vertex with exactly two face sides share a fan.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    (S,) int64
        Fan labels numbered from 0; a vertex with more than one label is pinched.
    """
    halfedges = mesh.halfedges  # (S, 2)
    nxt = mesh.next_corner  # (S,)
    n_corners = len(halfedges)
    if n_corners == 0:
        return np.zeros(0, dtype=np.int64)
    keys = edge_keys(halfedges, mesh.n_vertices)
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    _, start, counts = np.unique(sorted_keys, return_index=True, return_counts=True)
    pair = counts == 2
    c1 = order[start[pair]]
    c2 = order[start[pair] + 1]
    # Corner c is at halfedges[c, 0]; its face's corner at halfedges[c, 1] is nxt[c].
    same_dir = halfedges[c1, 0] == halfedges[c2, 0]
    a1 = c1
    b1 = np.where(same_dir, c2, nxt[c2])  # the other face's corner at the origin of c1
    a2 = nxt[c1]
    b2 = np.where(same_dir, nxt[c2], c2)  # ... at the target of c1
    pairs = np.stack([np.concatenate([a1, a2]), np.concatenate([b1, b2])], axis=1)  # (E, 2)
    _, label = component_labels(n_corners, pairs)  # (S,)
    return label


def edge_connected_faces(mesh: PolygonMesh) -> tuple[int, IntArray]:
    """Components of the faces, two faces joined when they share an edge (compare
    :func:`vertex_connected_faces`, where a shared vertex is enough).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    n_components : int
    label : (F,) int64
        Component of each face, numbered in order of each component's first face.
    """
    if mesh.n_faces == 0:
        return 0, np.zeros(0, dtype=np.int64)
    return component_labels(mesh.n_faces, face_adjacency(mesh))


def face_adjacency(mesh: PolygonMesh) -> IntArray:
    """Pairs of faces that share an edge.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    (E, 2) int64
        One row per two sides of an edge that follow each other in edge order (one row
        per interior edge of a manifold mesh).
    """
    face = mesh.face_of_corner
    keys = edge_keys(mesh.halfedges, mesh.n_vertices)
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    same = sk[1:] == sk[:-1]
    return np.stack([face[order[:-1][same]], face[order[1:][same]]], axis=1)  # (E, 2)


def vertex_connected_faces(mesh: PolygonMesh, faces: BoolArray | None = None
                           ) -> tuple[int, IntArray]:
    """Components of the faces ``faces``, two faces joined when they share a vertex
    (compare :func:`edge_connected_faces`, where they must share an edge).

    Parameters
    ----------
    mesh : PolygonMesh
    faces : (F,) bool, optional
        The faces to group (all by default); the others join nothing.

    Returns
    -------
    n_components : int
        0 when no face is chosen.
    label : (F,) int64
        Component of each chosen face, numbered in order of each component's first face;
        -1 for the others.
    """
    n_f, n_v = mesh.n_faces, mesh.n_vertices
    chosen = np.ones(n_f, dtype=bool) if faces is None else faces  # (F,)
    corner = chosen[mesh.face_of_corner]  # (S,) corners of chosen faces
    # nodes: the faces, then the vertices; a corner joins its face with its vertex
    pairs = np.stack([mesh.face_of_corner[corner], n_f + mesh.face_indices[corner]], axis=1)
    _, label = component_labels(n_f + n_v, pairs)  # (F + V,)
    ids, group = np.unique(label[:n_f][chosen], return_inverse=True)
    out = np.full(n_f, -1, dtype=np.int64)
    out[chosen] = group.reshape(-1)
    return len(ids), out


def check_topology(mesh: PolygonMesh) -> TopologyReport:
    """Count every topological defect of ``mesh``.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    TopologyReport
    """
    sizes = mesh.face_sizes
    halfedges = mesh.halfedges
    face = mesh.face_of_corner

    # Faces that visit a vertex twice: duplicate (face, vertex) pairs.
    fv = np.sort(face * max(mesh.n_vertices, 1) + mesh.face_indices)  # (S,)
    repeated = fv[1:][fv[1:] == fv[:-1]]  # a pair once per repeat
    n_repeated = len(np.unique(repeated // max(mesh.n_vertices, 1)))

    keys = edge_keys(halfedges, mesh.n_vertices)
    uniq, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    n_edges = len(uniq)
    boundary = int(np.sum(counts == 1))
    nonmanifold = int(np.sum(counts > 2))
    # Orientation: for edges with exactly two sides, the directions must differ.
    forward = halfedges[:, 0] < halfedges[:, 1]
    n_forward = np.bincount(inverse, weights=forward, minlength=n_edges)
    misoriented = int(np.sum((counts == 2) & (n_forward != 1)))

    fans = count_vertex_fans(mesh)
    used = np.zeros(mesh.n_vertices, dtype=bool)
    used[mesh.face_indices] = True
    n_components, _ = edge_connected_faces(mesh)
    euler = int(used.sum()) - n_edges + mesh.n_faces
    return TopologyReport(
        n_vertices=mesh.n_vertices,
        n_faces=mesh.n_faces,
        n_edges=n_edges,
        n_small_faces=int(np.sum(sizes < 3)),
        n_repeated_vertex_faces=n_repeated,
        n_boundary_edges=boundary,
        n_nonmanifold_edges=nonmanifold,
        n_misoriented_edges=misoriented,
        n_nonmanifold_vertices=int(np.sum(fans > 1)),
        n_unreferenced_vertices=int(np.sum(~used)),
        n_components=n_components,
        euler_characteristic=euler,
    )


@dataclass(frozen=True)
class SurfaceTopology:
    """What a user sees of a mesh's topology: its pieces, their genus, its open rims.

    ``pieces`` are the components of faces connected through shared edges, after equal
    positions are welded; ``genus`` is ``(2 pieces - chi - boundary_loops) / 2`` (summed
    over pieces, ``chi = V - E + F`` of the welded mesh); ``boundary_loops`` are the
    connected runs of edges with one face.
    """

    pieces: int
    genus: int
    boundary_loops: int


def weld_equal_positions(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` with vertices at exactly equal positions merged (:func:`spacemesh.primitives.weld`).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    PolygonMesh
        Same faces, indices into the distinct positions (in lexicographic order).
    """
    if mesh.n_vertices == 0:
        return mesh
    vertices, inverse = weld(np.asarray(mesh.vertices, dtype=np.float64))
    return PolygonMesh(vertices, inverse[mesh.face_indices], mesh.face_offsets)


def surface_topology(mesh: PolygonMesh) -> SurfaceTopology:
    """Pieces, genus and boundary loops of ``mesh`` after welding equal positions.

    Parameters
    ----------
    mesh : PolygonMesh
        Edge-manifold for the genus to mean what it says (every output of the service is).

    Returns
    -------
    SurfaceTopology
        All zero for a mesh without faces.
    """
    if mesh.n_faces == 0:
        return SurfaceTopology(pieces=0, genus=0, boundary_loops=0)
    welded = weld_equal_positions(mesh)
    pieces, _ = edge_connected_faces(welded)
    keys = edge_keys(welded.halfedges, welded.n_vertices)
    unique, counts = np.unique(keys, return_counts=True)
    used = np.zeros(welded.n_vertices, dtype=bool)
    used[welded.face_indices] = True
    euler = int(used.sum()) - len(unique) + welded.n_faces
    open_keys = unique[counts == 1]  # (B,) edges with one face
    loops = 0
    if len(open_keys):
        n = max(welded.n_vertices, 1)
        a, b = open_keys // n, open_keys % n
        _, label = component_labels(n, np.stack([a, b], axis=1))  # (V,)
        loops = len(np.unique(label[np.concatenate([a, b])]))
    return SurfaceTopology(pieces=int(pieces), genus=int((2 * pieces - euler - loops) // 2),
                           boundary_loops=int(loops))
