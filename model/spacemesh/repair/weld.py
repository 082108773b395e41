"""Welding vertices split at seams, the opt-in first step of a repair (``weld=True``).

Files from games and DCC tools, GLB and glTF above all, split a vertex wherever its
UV coordinates or normal change (UV seams, hard edges, flat shading): the copies share
a position but not an index, so the readers (which never weld) hand over a mesh that is
open along every seam, and a repair answers ``defects-outside-region``. Welding merges
vertices at *exactly* equal positions (``-0.0`` equals ``0.0``; nothing is snapped
within a tolerance), with :func:`spacemesh.primitives.weld`, the STL reader's own weld.

Rules (see docs/REPAIR.md):

- Vertices keep the order of their first occurrence: welded vertex ``n`` is the
  ``n``-th distinct position met going through the vertices in order, at that first
  copy's position. Faces keep their count, order and corners, renumbered.
- A face that welding leaves with a repeated vertex is kept as it is (nothing the user
  sent is dropped silently): it is a degenerate face, a defect the region must cover.
- A ``{"vertices": [...]}`` region names vertices of the file: each index goes through
  the old -> new map (so it selects every face around that position). Face indices and
  sphere and box regions mean the same faces before and after welding.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import weld
from spacemesh.repair.region import Region, check_range, parse_region
from spacemesh.typed import BoolArray, IntArray


def weld_vertices(mesh: PolygonMesh) -> tuple[PolygonMesh, IntArray]:
    """Merge the vertices of ``mesh`` that have exactly the same position.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    welded : PolygonMesh
        One vertex per distinct position, in order of first occurrence; the same faces
        (count, order, corners), renumbered. A face may now repeat a vertex.
    vertex_map : (V,) int64
        Index in ``welded`` of each vertex of ``mesh``
        (``welded.vertices[vertex_map] == mesh.vertices``).
    """
    if mesh.n_vertices == 0:
        return mesh, np.zeros(0, dtype=np.int64)
    _, group = weld(mesh.vertices)  # groups in lexicographic order
    n_groups = int(group.max()) + 1
    first = np.full(n_groups, mesh.n_vertices, dtype=np.int64)
    np.minimum.at(first, group, np.arange(mesh.n_vertices, dtype=np.int64))
    order = np.argsort(first, kind="stable")  # groups by first occurrence
    rank = np.empty(n_groups, dtype=np.int64)
    rank[order] = np.arange(n_groups, dtype=np.int64)
    vertex_map = rank[group]
    welded = PolygonMesh(mesh.vertices[first[order]], vertex_map[mesh.face_indices],
                         mesh.face_offsets)
    return welded, vertex_map


def coincident_vertices(mesh: PolygonMesh) -> int:
    """How many vertices :func:`weld_vertices` would merge away (0: none share a position).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    int
        ``mesh.n_vertices`` minus the number of distinct positions.
    """
    if mesh.n_vertices == 0:
        return 0
    distinct, _ = weld(mesh.vertices)
    return mesh.n_vertices - len(distinct)


def weld_region(region: Region | Mapping[str, Any] | BoolArray, vertex_map: IntArray
                ) -> Region | BoolArray:
    """A region of the original mesh as a region of its welded mesh.

    Parameters
    ----------
    region : Region, dict (JSON form) or (F,) bool face mask
        In the original mesh's indices.
    vertex_map : (V,) int64
        From :func:`weld_vertices`.

    Returns
    -------
    Region or (F,) bool
        Vertex indices mapped through ``vertex_map``; any other region as it was (faces
        and positions do not change).

    Raises
    ------
    RegionError
        ``invalid-region``: a malformed region, or a vertex index out of range of the
        original mesh.
    """
    if isinstance(region, np.ndarray) and region.dtype == bool:
        return region
    shape = parse_region(region)
    if shape.kind != "vertices":
        return shape
    check_range(shape.indices, len(vertex_map), "vertex", "vertices")
    return Region.from_vertices(vertex_map[shape.indices])


__all__ = ["coincident_vertices", "weld_region", "weld_vertices"]
