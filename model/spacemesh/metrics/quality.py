"""Intrinsic mesh quality: validity rates, self-intersections and element shapes (Fig. 9).

- :func:`topology_flags`: manifold, watertight, oriented and valid, from
  :func:`spacemesh.topology.check_topology` (connectivity only).
- :func:`self_intersection_fraction`: the fraction of polygon faces that intersect
  another face, by :mod:`spacemesh.geometry.intersections` (bounding-sphere candidates,
  each pair confirmed by an exact triangle test; triangles of one polygon are not
  compared; a polygon face counts when one of its triangles intersects). Unlike
  pymeshlab's per-face filter, which the metric used before 2026-12, it also finds
  coplanar triangles that overlap (a fold within a flat region).
- :func:`edge_lengths` and :func:`corner_angles`: the element-shape distributions, and
  :func:`distribution_distance`, the 1-D Wasserstein (earth mover's) distance between a
  prediction's distribution and the ground truth's, in the distribution's own units.
"""

from __future__ import annotations

import numpy as np

from spacemesh.geometry.intersections import (  # noqa: F401  (the metrics' definition)
    self_intersecting_faces,
    self_intersection_fraction,
)
from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology
from spacemesh.typed import FloatArray


def topology_flags(mesh: PolygonMesh, open_surface: bool = False) -> dict[str, bool | int]:
    """Connectivity validity of a mesh.

    Parameters
    ----------
    mesh : PolygonMesh
    open_surface : bool
        The mesh's maker declared it open (a generate's fit report ``open_surface``):
        boundary edges do not make it invalid
        (:meth:`spacemesh.topology.TopologyReport.is_valid`).

    Returns
    -------
    dict
        ``manifold`` (edge- and vertex-manifold, well-formed faces), ``watertight``
        (every edge has exactly two faces), ``oriented`` (neighbouring faces traverse
        shared edges in opposite directions), ``valid`` (all three, and not empty;
        watertight only unless ``open_surface``) and ``components``.
    """
    report = check_topology(mesh)
    nonempty = report.n_faces > 0
    return {
        "manifold": bool(report.is_manifold and nonempty),
        "watertight": bool(report.is_closed and report.is_edge_manifold and nonempty),
        "oriented": bool(report.is_oriented and nonempty),
        "valid": bool(report.is_valid(open_surface)),
        "components": int(report.n_components),
    }


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
