"""The discrete Laplace fairing of a patch: its free vertices solve ``L^k x = 0`` with
every other vertex fixed (a membrane, a thin plate, the tri-harmonic surface).

numpy and scipy only.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import MatrixRankWarning, spsolve

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    faces_subset,
    faces_touching,
    triangulate_faces,
    uniform_adjacency,
    vertices_of,
)
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Bounds of the cotangent weights of :func:`fair_positions` (obtuse angles give
#: negative cotangents, slivers huge ones).
MIN_COTANGENT, MAX_COTANGENT = 1e-3, 1e2
#: Solves of :func:`fair_positions` (the weights re-read from the last solution).
FAIR_SOLVES = 2


def laplacian(mesh: PolygonMesh, faces: BoolArray, uniform: bool = False) -> sp.csr_matrix:
    """``I - D^-1 W`` over the faces ``faces`` (each polygon fanned into triangles), with
    cotangent weights ``W`` clamped to [:data:`MIN_COTANGENT`, :data:`MAX_COTANGENT`] (a
    cotangent Laplacian measures the curvature of the fixed ring however its edges are
    laid out, where uniform weights would read an anisotropic ring as curved), or with
    ``uniform`` weights 1 on every edge
    (:func:`~spacemesh.primitives.graph.uniform_adjacency`), (V, V)."""
    triangles, _ = triangulate_faces(faces_subset(mesh, faces))  # (T, 3)
    n = mesh.n_vertices
    if uniform:
        sides = np.concatenate([triangles[:, [k, (k + 1) % 3]] for k in range(3)])  # (3T, 2)
        w = uniform_adjacency(n, sides)
    else:
        w = _cotangent_weights(np.asarray(mesh.vertices, dtype=np.float64), triangles)
    degree = np.asarray(w.sum(axis=1)).ravel()
    inverse = sp.diags(np.where(degree > 0, 1.0 / np.maximum(degree, 1e-300), 0.0))
    return (sp.identity(n, format="csr") - inverse @ w).tocsr()


def _cotangent_weights(p: FloatArray, triangles: IntArray) -> sp.csr_matrix:
    """(V, V) symmetric weights: half the clamped cotangent of the angle opposite each
    side of the (T, 3) ``triangles``, summed over the triangles, over the (V, 3)
    positions ``p``."""
    n = len(p)
    rows, cols, weights = [], [], []
    for k in range(3):
        i, j, o = triangles[:, k], triangles[:, (k + 1) % 3], triangles[:, (k + 2) % 3]
        u, v = p[i] - p[o], p[j] - p[o]
        sine = np.linalg.norm(np.cross(u, v), axis=1)
        cot = np.einsum("ij,ij->i", u, v) / np.maximum(sine, 1e-300)
        cot = np.clip(np.where(sine > 0, cot, MAX_COTANGENT), MIN_COTANGENT, MAX_COTANGENT)
        rows += [i, j]
        cols += [j, i]
        weights += [cot / 2, cot / 2]
    return sp.coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, n)).tocsr()


def fair_positions(mesh: PolygonMesh, free: BoolArray, order: int = 2,
                   weights: str = "cotangent") -> FloatArray:
    """Positions with the ``free`` vertices solving ``L^order x = 0``, the rest fixed.

    ``order`` 1 is a membrane (each free vertex at the mean of its neighbours), 2 a
    thin plate, whose boundary conditions are the fixed ring and the ring beyond it, 3
    the tri-harmonic surface, which reads a third ring and continues the curvature.
    Only the faces within ``order`` rings of the free vertices are read. A free part
    that no fixed vertex reaches keeps its positions.

    Parameters
    ----------
    mesh : PolygonMesh
    free : (V,) bool
    order : {1, 2, 3}
    weights : {"cotangent", "uniform"}
        Cotangent weights (re-read from the first solution, :data:`FAIR_SOLVES` solves)
        or the uniform umbrella (one solve).

    Returns
    -------
    (V, 3) float64
    """
    positions = np.asarray(mesh.vertices, dtype=np.float64).copy()
    if not free.any():
        return positions
    near = free.copy()
    for _ in range(order - 1):
        near |= vertices_of(mesh, faces_touching(mesh, near))
    faces = faces_touching(mesh, near)
    # the system over the vertices of those faces only, numbered in the same order (the
    # same matrices, entry for entry and in the same order, without (V, V) work per call)
    local = np.flatnonzero(vertices_of(mesh, faces) | free)
    number = np.full(mesh.n_vertices, -1, dtype=np.int64)
    number[local] = np.arange(len(local))
    chosen = faces_subset(mesh, faces)
    sub = PolygonMesh(positions[local], number[chosen.face_indices], chosen.face_offsets)
    positions[local] = _fair_all(sub, free[local], order, weights)
    return positions


def _fair_all(mesh: PolygonMesh, free: BoolArray, order: int, weights: str) -> FloatArray:
    """:func:`fair_positions` over every face of ``mesh`` (the faces it reads)."""
    positions = np.asarray(mesh.vertices, dtype=np.float64).copy()
    faces = np.ones(mesh.n_faces, dtype=bool)
    rows = np.flatnonzero(free)
    fixed = ~free
    for _ in range(FAIR_SOLVES if weights == "cotangent" else 1):
        lap = laplacian(mesh.with_vertices(positions), faces, weights == "uniform")
        system = lap
        for _ in range(order - 1):
            system = lap @ system
        a = system[rows][:, rows].tocsc()
        rhs = -(system[rows][:, fixed] @ positions[fixed])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", MatrixRankWarning)
                solved = np.asarray(spsolve(a, rhs)).reshape(len(rows), 3)
        except (RuntimeError, MatrixRankWarning):  # singular: a part no fixed vertex reaches
            break
        if not np.isfinite(solved).all():
            break
        positions[rows] = solved
    return positions
