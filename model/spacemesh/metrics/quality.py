"""Intrinsic mesh quality: validity rates, self-intersections and element shapes (Fig. 9).

- :func:`topology_flags`: manifold, watertight, oriented and valid, from
  :func:`spacemesh.topology.check_topology` (connectivity only).
- :func:`self_intersection_fraction`: the fraction of polygon faces that intersect
  another face. Candidates come from pymeshlab's
  ``compute_selection_by_self_intersections_per_face`` on the triangulation; each
  candidate pair is then confirmed with :func:`spacemesh.data.validate.triangles_intersect`
  (VCG's test reports separated coplanar triangles as intersecting), skipping the
  triangles of one polygon; a polygon face counts when one of its triangles intersects.
- :func:`edge_lengths` and :func:`corner_angles`: the element-shape distributions, and
  :func:`distribution_distance`, the 1-D Wasserstein (earth mover's) distance between a
  prediction's distribution and the ground truth's, in the distribution's own units.
"""

from __future__ import annotations

import numpy as np

from spacemesh.data.validate import triangles_intersect, triangles_of
from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Relative shrink of triangles that share corners before the intersection test, so that
#: touching at the shared corner or edge does not count (as in :mod:`spacemesh.data.validate`).
SHRINK = 1e-6


def topology_flags(mesh: PolygonMesh) -> dict[str, bool | int]:
    """Connectivity validity of a mesh.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    dict
        ``manifold`` (edge- and vertex-manifold, well-formed faces), ``watertight``
        (every edge has exactly two faces), ``oriented`` (neighbouring faces traverse
        shared edges in opposite directions), ``valid`` (all three, and not empty) and
        ``components``.
    """
    report = check_topology(mesh)
    nonempty = report.n_faces > 0
    return {
        "manifold": bool(report.is_manifold and nonempty),
        "watertight": bool(report.is_closed and report.is_edge_manifold and nonempty),
        "oriented": bool(report.is_oriented and nonempty),
        "valid": bool(report.is_closed_oriented_manifold),
        "components": int(report.n_components),
    }


def _candidate_triangles(vertices: FloatArray, tri: IntArray) -> IntArray:
    """Triangles that pymeshlab's self-intersection filter selects (a superset)."""
    import pymeshlab

    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=vertices, face_matrix=tri.astype(np.int32)))
    meshset.compute_selection_by_self_intersections_per_face()
    return np.flatnonzero(meshset.current_mesh().face_selection_array())


def _shrink(points: FloatArray) -> FloatArray:
    centre = points.mean(axis=0)
    return centre + (points - centre) * (1.0 - SHRINK)


def self_intersecting_faces(mesh: PolygonMesh, *, confirm: bool = True) -> BoolArray:
    """Which polygon faces intersect another face of the mesh.

    Parameters
    ----------
    mesh : PolygonMesh
    confirm : bool
        Confirm pymeshlab's candidates pair by pair (see the module doc).

    Returns
    -------
    (F,) bool
    """
    hit = np.zeros(mesh.n_faces, dtype=bool)
    if mesh.n_faces < 2:
        return hit
    tri, source = triangles_of(mesh)  # (T, 3), (T,)
    candidates = _candidate_triangles(mesh.vertices, tri)
    if not confirm:
        hit[source[candidates]] = True
        return hit
    if candidates.size < 2:
        return hit
    extent = float(np.ptp(mesh.vertices, axis=0).max()) / 2 or 1.0
    eps = 1e-9 * extent
    pts = mesh.vertices[tri[candidates]]  # (C, 3, 3)
    lo, hi = pts.min(axis=1) - eps, pts.max(axis=1) + eps  # (C, 3) each
    confirmed = np.zeros(len(candidates), dtype=bool)
    for i in range(len(candidates) - 1):
        overlap = np.all((lo[i + 1 :] <= hi[i]) & (hi[i + 1 :] >= lo[i]), axis=1)
        for j in np.flatnonzero(overlap) + i + 1:
            if confirmed[i] and confirmed[j]:
                continue
            fa, fb = candidates[i], candidates[j]
            if source[fa] == source[fb]:
                continue
            ta, tb = pts[i], pts[j]
            if np.intersect1d(tri[fa], tri[fb]).size:
                ta, tb = _shrink(ta), _shrink(tb)
            if triangles_intersect(ta, tb, eps):
                confirmed[i] = confirmed[j] = True
    hit[source[candidates[confirmed]]] = True
    return hit


def self_intersection_fraction(mesh: PolygonMesh, *, confirm: bool = True) -> float:
    """The fraction (in [0, 1]) of faces that intersect another face (0 for no faces)."""
    if mesh.n_faces == 0:
        return 0.0
    return float(self_intersecting_faces(mesh, confirm=confirm).mean())


def edge_lengths(mesh: PolygonMesh) -> FloatArray:
    """(E,) length of every undirected edge."""
    e = mesh.edges  # (E, 2)
    return np.linalg.norm(mesh.vertices[e[:, 1]] - mesh.vertices[e[:, 0]], axis=1)


def corner_angles(mesh: PolygonMesh) -> FloatArray:
    """(S,) interior angle at every polygon corner, in degrees.

    The angle between a corner's two sides; at a reflex corner of a non-convex polygon
    (turning against the face's Newell normal) it is 360 degrees minus that.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    (S,) float64
        One angle per entry of ``mesh.face_indices``; degenerate corners give 0.
    """
    if mesh.n_faces == 0:
        return np.zeros(0)
    nxt = mesh.next_corner  # (S,)
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(nxt))
    v = mesh.vertices
    here = v[mesh.face_indices]
    a = v[mesh.face_indices[prv]] - here  # (S, 3)
    b = v[mesh.face_indices[nxt]] - here  # (S, 3)
    la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    ok = (la > 0) & (lb > 0)
    cos = np.einsum("sd,sd->s", a, b) / np.where(ok, la * lb, 1.0)
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    normal = mesh.face_normals()[mesh.face_of_corner]  # (S, 3)
    reflex = np.einsum("sd,sd->s", np.cross(b, a), normal) < 0
    return np.where(ok, np.where(reflex, 360.0 - angle, angle), 0.0)


def distribution_distance(values: FloatArray, reference: FloatArray) -> float:
    """1-D Wasserstein distance between two samples of a distribution (NaN if one is empty).

    Parameters
    ----------
    values, reference : (N,), (M,) float

    Returns
    -------
    float
    """
    from scipy.stats import wasserstein_distance

    if len(values) == 0 or len(reference) == 0:
        return float("nan")
    return float(wasserstein_distance(values, reference))


def degree_histogram(mesh: PolygonMesh) -> dict[int, int]:
    """Face-degree counts, e.g. ``{3: 120, 4: 8}`` (see :meth:`PolygonMesh.degree_histogram`)."""
    return mesh.degree_histogram()
