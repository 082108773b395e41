"""Scores of meshes made from one-sided scans: how much of what was seen they cover.

A one-sided scan keeps the points whose true normal has a positive component along
the scan direction (:func:`one_sided`). Its output is scored against the ground truth
and the part of it that was seen (:func:`seen_faces`: the faces whose normal has a
positive component along the direction) by :func:`scan_scores`:

* ``accuracy``: mean distance from points spread over the output to the ground truth;
* ``completeness``: mean distance from points spread over the seen part to the output;
* ``area_ratio``: the output's area over the seen part's;
* ``open``: the output has boundary edges;
* ``valid``: edge- and vertex-manifold and oriented (closed or not), with faces.

Distances are in the frame of the meshes given (the evaluation's unit frame).
:func:`trim_to_points` is how a closed baseline is made comparable: faces whose
centroid lies farther than 2.5 mean point spacings from every point are removed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    faces_subset,
    sample_surface,
    surface_area,
    triangles_of,
)
from spacemesh.primitives.closest import mean_spacing, nearest_triangles
from spacemesh.topology import check_topology
from spacemesh.typed import BoolArray, FloatArray

#: Points spread over each surface a score measures.
SCAN_SAMPLES = 20_000
#: A baseline's faces farther than this many mean point spacings from every point go.
TRIM_SPACINGS = 2.5


def one_sided(normals: FloatArray, direction: FloatArray) -> BoolArray:
    """(P,) the points a scan along ``direction`` keeps: true normal along it.

    Parameters
    ----------
    normals : (P, 3) float
    direction : (3,) float

    Returns
    -------
    (P,) bool
    """
    return np.asarray(normals, dtype=np.float64) @ np.asarray(direction, np.float64) > 0


def seen_faces(mesh: PolygonMesh, direction: FloatArray) -> BoolArray:
    """(F,) faces whose normal has a positive component along ``direction``.

    Parameters
    ----------
    mesh : PolygonMesh
    direction : (3,) float

    Returns
    -------
    (F,) bool
    """
    return mesh.face_normals() @ np.asarray(direction, dtype=np.float64) > 0


def trim_to_points(mesh: PolygonMesh, points: FloatArray,
                   spacings: float = TRIM_SPACINGS) -> PolygonMesh:
    """``mesh`` without the faces whose centroid is farther than ``spacings`` mean
    point spacings from every point.

    Parameters
    ----------
    mesh : PolygonMesh
    points : (P, 3) float
    spacings : float

    Returns
    -------
    PolygonMesh
        Unused vertices removed.
    """
    points = np.asarray(points, dtype=np.float64)
    distance, _ = cKDTree(points).query(mesh.face_centroids())  # (F,)
    spacing = mean_spacing(points)
    trimmed, _ = faces_subset(mesh, distance <= spacings * spacing).remove_unreferenced_vertices()
    return trimmed


def _distance_to(mesh: PolygonMesh, points: FloatArray) -> FloatArray:
    """(P,) distance from each point to ``mesh``."""
    triangles, _ = triangles_of(mesh)
    _, gap = nearest_triangles(points, mesh.vertices, triangles)
    return np.sqrt(gap)


def scan_scores(output: PolygonMesh, truth: PolygonMesh, direction: FloatArray, *,
                seed: Any = 0, samples: int = SCAN_SAMPLES) -> dict[str, float | bool]:
    """The scores of the module docstring for one output.

    Parameters
    ----------
    output : PolygonMesh
    truth : PolygonMesh
        The ground truth, closed.
    direction : (3,) float
        The scan direction.
    seed : int or sequence of int
        Seed of the surface samples.
    samples : int

    Returns
    -------
    dict
        ``accuracy``, ``completeness``, ``area_ratio``, ``open``, ``valid`` (NaN and
        False for an output without faces).
    """
    seen = faces_subset(truth, seen_faces(truth, direction))
    seen_area = surface_area(seen)
    if output.n_faces == 0:
        return {"accuracy": np.nan, "completeness": np.nan, "area_ratio": 0.0,
                "open": False, "valid": False}
    rng = np.random.default_rng(seed)
    on_output, _ = sample_surface(output, samples, rng)
    on_seen, _ = sample_surface(seen, samples, rng)
    report = check_topology(output)
    return {
        "accuracy": float(_distance_to(truth, on_output).mean()),
        "completeness": float(_distance_to(output, on_seen).mean()),
        "area_ratio": surface_area(output) / seen_area if seen_area > 0 else np.nan,
        "open": bool(report.n_boundary_edges > 0),
        "valid": bool(report.is_manifold and report.is_oriented and output.n_faces > 0),
    }


__all__ = ["one_sided", "scan_scores", "seen_faces", "trim_to_points"]
