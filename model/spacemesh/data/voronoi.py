"""Restricted Delaunay meshes: the connectivity a surface gives a chosen vertex set.

The serving pipeline's vertices are farthest points of the input cloud
(:func:`spacemesh.geometry.farthest_point_sampling`), not the vertices of a QEM mesh.
To train the connectivity network on the vertex sets it meets, the ``farthest`` style
(:mod:`spacemesh.data.styles`) needs the mesh those vertices *should* make on the true
surface: the dual of their geodesic Voronoi diagram on it, the restricted Delaunay
triangulation.

:func:`restricted_delaunay` approximates it on a dense triangulation of the surface:
each site is snapped to its nearest dense vertex, every dense vertex is labelled with
its geodesically nearest site (multi-source Dijkstra over the dense edges), and each
dense triangle whose three corners carry three different labels gives one triangle of
the result, oriented as the dense triangle is. The result is a closed oriented manifold
when every Voronoi region is a disk and no four regions meet at a point; callers check
it (the data validator rejects the rest). Vertices are the sites themselves, not their
snapped positions.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangles_of
from spacemesh.typed import FloatArray, IntArray


def voronoi_labels(vertices: FloatArray, triangles: IntArray, seeds: IntArray) -> IntArray:
    """(V,) index into ``seeds`` of each vertex's geodesically nearest seed (-1 where
    none is reachable), distances measured along the triangles' edges.

    Parameters
    ----------
    vertices : (V, 3) float
    triangles : (T, 3) int
    seeds : (S,) int
        Distinct vertex indices.
    """
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                            triangles[:, [2, 0]]])  # (3T, 2)
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    graph = coo_matrix((lengths, (edges[:, 0], edges[:, 1])),
                       shape=(len(vertices), len(vertices))).tocsr()
    _, _, source = dijkstra(graph, directed=False, indices=seeds, min_only=True,
                            return_predecessors=True)
    order = np.full(len(vertices), -1, dtype=np.int64)
    order[seeds] = np.arange(len(seeds))
    return np.where(source >= 0, order[np.maximum(source, 0)], -1)


def restricted_delaunay(dense: PolygonMesh, sites: FloatArray) -> PolygonMesh:
    """The restricted Delaunay triangle mesh of ``sites`` on the surface ``dense``.

    Parameters
    ----------
    dense : PolygonMesh
        A closed oriented surface, triangulated much finer than the sites' spacing.
    sites : (S, 3) float
        Points on (or near) the surface.

    Returns
    -------
    PolygonMesh
        Vertices: the sites (those that share a dense vertex with an earlier site and
        those without a triangle left out); faces: one per dense triangle with three
        different labels, duplicates removed. Not checked (see the module docstring).
    """
    triangles, _ = triangles_of(dense)  # (T, 3)
    sites = np.asarray(sites, dtype=np.float64).reshape(-1, 3)
    _, snapped = cKDTree(dense.vertices).query(sites)  # (S,)
    seeds, first = np.unique(snapped, return_index=True)
    labels = voronoi_labels(dense.vertices, triangles, seeds)[triangles]  # (T, 3)
    distinct = ((labels[:, 0] != labels[:, 1]) & (labels[:, 1] != labels[:, 2])
                & (labels[:, 0] != labels[:, 2]) & (labels >= 0).all(axis=1))
    faces = labels[distinct]  # (F, 3), oriented as the dense triangles
    if len(faces) == 0:
        return PolygonMesh.empty()
    start = np.argmin(faces, axis=1)  # rotate each to start at its smallest label
    rows = np.arange(len(faces))
    faces = np.stack([faces[rows, (start + k) % 3] for k in range(3)], axis=1)
    faces = np.unique(faces, axis=0)
    mesh = PolygonMesh.from_faces(sites[first], list(faces))
    kept, _ = mesh.remove_unreferenced_vertices()
    return kept
