"""Vertex positions fitted to the conditioning points: one energy, one sparse solve.

After the decode has fixed the connectivity, the vertices move so that the mesh passes
through the points, as in Hoppe et al. 1993 ("Mesh Optimization"), with the tangent
planes of the points added so that vertices near creases and corners go onto them, as
dual contouring's QEF does. With the points' closest-point assignments held fixed, the
energy of the vertex positions ``V`` (N, 3) is quadratic::

    E(V) =  w_d / P  sum_i || p_i - sum_k b_ik v_k ||^2              points -> mesh
          + w_f / S  sum_s ( n_q(s) . (sum_k c_sk v_k - q(s)) )^2     mesh -> points
          + w_q / N  sum_v sum_j g_vj ( n_j . (v - p_j) )^2           tangent planes (QEF)
          + w_s / E  sum_(a,b) || v_a - v_b ||^2                      springs
          + w_r / N  sum_v || v - v_prev ||^2                         step damping

* ``b_ik``: barycentric coordinates of point ``p_i``'s closest point on its nearest
  triangle (Hoppe's projection step);
* ``q(s)``: the input point nearest to surface sample ``s`` (a fixed barycentric
  position ``c_s`` on a triangle), with that point's normal ``n_q``: faces come close
  to the points, point-to-plane so that faces may slide along the surface;
* ``g_vj``: Gaussian weights of the points ``p_j`` nearest to vertex ``v``, with their
  normals ``n_j``: in a flat region the planes agree and only the normal direction is
  held (the vertex stays where it is in the plane); near a crease two families of
  planes meet and the minimiser is on the crease line; near a corner, at the corner;
* springs (graph Laplacian) keep the system well posed where no point pulls.

The solver alternates the projection (closest points, nearest points, neighbourhoods)
with one sparse symmetric solve of the ``3N`` normal equations (the tangent planes
couple a vertex's coordinates). Only positions change here, so the connectivity,
hence the manifold guarantee, is untouched; :func:`spacemesh.geometry.stage.refine_geometry`
adds the edge operations. Normals: the upload's when it has them, otherwise
:func:`estimate_point_normals` (the sign does not matter to any term).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from spacemesh.cancel import checkpoint
from spacemesh.primitives import triangle_areas, unique_edges
from spacemesh.primitives.closest import (
    _subtriangle_centroids,
    nearest_points,
)
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Neighbours of the plane fit of :func:`estimate_point_normals`.
NORMAL_NEIGHBOURS = 12


@dataclass(frozen=True)
class VertexFitOptions:
    """Weights and rounds of the vertex fit (see the module docstring).

    Attributes
    ----------
    iterations : int
        Projection / solve rounds.
    data_weight : float
        ``w_d``, points -> mesh.
    face_weight : float
        ``w_f``, mesh -> points.
    plane_weight : float
        ``w_q``, the tangent-plane quadric (sharp features); 0 turns it off.
    plane_neighbours : int
        Nearest points considered for each vertex's quadric.
    plane_reach : float
        Their Gaussian weights fall off over this fraction of the vertex's mean edge
        length.
    spring_weight : float
        ``w_s`` (every term is a mean of squared lengths, so weights are scale-free).
    noise_spring : float
        Added to ``w_s`` times ``(sigma / mean edge length)^2``, where ``sigma`` is the
        points' noise (:func:`point_noise`): noisy points get a smoother surface.
    damping : float
        ``w_r``.
    face_samples : int
        Surface samples per triangle of the mesh -> points term (1, 4 or 7).
    """

    iterations: int = 6
    data_weight: float = 1.0
    face_weight: float = 1.0
    plane_weight: float = 1.0
    plane_neighbours: int = 8
    plane_reach: float = 0.5
    spring_weight: float = 1e-3
    noise_spring: float = 5.0
    damping: float = 1e-3
    face_samples: int = 4


def plane_fits(points: FloatArray, k: int = NORMAL_NEIGHBOURS) -> tuple[FloatArray, float]:
    """Plane fits to each point's ``k`` nearest neighbours: their normals and the noise.

    Parameters
    ----------
    points : (P, 3) float
    k : int

    Returns
    -------
    normals : (P, 3) float64
        The direction of least variance of each neighbourhood (sign arbitrary; +z for
        fewer than 3 points).
    noise : float
        The median standard deviation of the neighbourhoods about their planes (0 for
        points on a smooth surface).
    """
    points = np.asarray(points, dtype=np.float64)
    k = int(min(k, len(points)))
    if k < 3:
        return np.tile([0.0, 0.0, 1.0], (len(points), 1)), 0.0
    _, near = cKDTree(points).query(points, k=k)
    patch = points[near] - points[near].mean(axis=1, keepdims=True)  # (P, k, 3)
    covariance = np.einsum("pki,pkj->pij", patch, patch)  # (P, 3, 3)
    values, vectors = np.linalg.eigh(covariance)  # ascending
    noise = float(np.sqrt(np.median(np.maximum(values[:, 0], 0.0) / k)))
    return vectors[:, :, 0], noise


def estimate_point_normals(points: FloatArray, k: int = NORMAL_NEIGHBOURS) -> FloatArray:
    """Unoriented unit normals of :func:`plane_fits`."""
    return plane_fits(points, k)[0]


def point_noise(points: FloatArray, k: int = NORMAL_NEIGHBOURS) -> float:
    """The points' noise of :func:`plane_fits`."""
    return plane_fits(points, k)[1]


def barycentric(points: FloatArray, corners: FloatArray) -> FloatArray:
    """Barycentric coordinates of points that lie on their triangles.

    Parameters
    ----------
    points : (M, 3) float
    corners : (M, 3, 3) float

    Returns
    -------
    (M, 3) float64
        Rows sum to 1; a degenerate triangle gives its centroid's coordinates.
    """
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    e0, e1, ep = b - a, c - a, points - a
    d00 = np.einsum("md,md->m", e0, e0)
    d01 = np.einsum("md,md->m", e0, e1)
    d11 = np.einsum("md,md->m", e1, e1)
    d20 = np.einsum("md,md->m", ep, e0)
    d21 = np.einsum("md,md->m", ep, e1)
    denominator = d00 * d11 - d01 * d01
    good = denominator > 1e-30 * np.maximum(d00 * d11, 1e-300)
    safe = np.where(good, denominator, 1.0)
    v = np.where(good, (d11 * d20 - d01 * d21) / safe, 1 / 3)
    w = np.where(good, (d00 * d21 - d01 * d20) / safe, 1 / 3)
    out = np.column_stack([1.0 - v - w, v, w])
    return np.clip(out, 0.0, 1.0) / np.clip(out, 0.0, 1.0).sum(axis=1, keepdims=True)


def _sample_weights(count: int) -> FloatArray:
    """Fixed barycentric positions ``(S, 3)`` of the mesh -> points samples."""
    if count <= 1:
        return np.full((1, 3), 1 / 3)
    inner = np.array([[4, 1, 1], [1, 4, 1], [1, 1, 4]], dtype=np.float64) / 6
    rows = [np.full((1, 3), 1 / 3), inner]
    if count >= 7:
        rows.append(np.array([[1, 1, 0], [0, 1, 1], [1, 0, 1]], dtype=np.float64) / 2)
    return np.concatenate(rows)


def _plane_rows(columns: IntArray, weights: FloatArray, normals: FloatArray, n_vertices: int
                ) -> sp.csr_matrix:
    """Rows ``n . (sum_k w_k v_{c_k})`` over the ``3N`` unknowns (vertex-major)."""
    m, k = columns.shape
    index = (3 * columns[:, :, None] + np.arange(3)).reshape(m, -1)  # (M, 3k)
    values = (weights[:, :, None] * normals[:, None, :]).reshape(m, -1)  # (M, 3k)
    rows = np.repeat(np.arange(m), 3 * k)
    return sp.csr_matrix((values.ravel(), (rows, index.ravel())), shape=(m, 3 * n_vertices))


def _point_rows(columns: IntArray, weights: FloatArray, n_vertices: int) -> sp.csr_matrix:
    """Rows ``sum_k w_k v_{c_k}`` (one per point) over the ``N`` vertices."""
    m, k = columns.shape
    rows = np.repeat(np.arange(m), k)
    return sp.csr_matrix((weights.ravel(), (rows, columns.ravel())), shape=(m, n_vertices))


def _vertex_reach(positions: FloatArray, edges: IntArray) -> FloatArray:
    """``(N,)`` mean length of each vertex's edges (the mean over all for none)."""
    length = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    total = np.bincount(edges.reshape(-1), np.repeat(length, 2), len(positions))
    count = np.bincount(edges.reshape(-1), minlength=len(positions))
    fallback = float(length.mean()) if len(length) else 1.0
    return np.where(count > 0, total / np.maximum(count, 1), fallback)


def _edges(triangles: IntArray) -> IntArray:
    pairs = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return unique_edges(pairs, int(triangles.max(initial=-1)) + 1)


def _incidence(edges: IntArray, n_vertices: int) -> sp.csr_matrix:
    """``(E, N)`` rows ``v_a - v_b`` of the edges: ``D^T D`` is the springs' graph
    Laplacian."""
    m = len(edges)
    return sp.csr_matrix(
        (np.tile([1.0, -1.0], m), (np.repeat(np.arange(m), 2), edges.reshape(-1))),
        shape=(m, n_vertices),
    )


def fit_energy_terms(
    positions: FloatArray, triangles: IntArray, points: FloatArray, normals: FloatArray,
    tree: cKDTree, options: VertexFitOptions,
) -> tuple[sp.csr_matrix, FloatArray, float]:
    """The normal equations ``A x = r`` of the energy at the current projection.

    Parameters
    ----------
    positions : (N, 3) float
    triangles : (T, 3) int
    points, normals : (P, 3) float
    tree : cKDTree
        Of ``points``.
    options : VertexFitOptions

    Returns
    -------
    A : (3N, 3N) sparse
    r : (3N,) float
    energy : float
        The energy at ``positions`` (without damping).
    """
    n = len(positions)
    x = positions.reshape(-1)
    edges = _edges(triangles)
    blocks: list[sp.spmatrix] = []
    rhs = np.zeros(3 * n)
    energy = 0.0

    # points -> mesh: p_i ~ sum_k b_ik v_k (each coordinate)
    owner, _, closest = nearest_points(points, positions, triangles)
    corners = positions[triangles[owner]]  # (P, 3, 3)
    bary = barycentric(closest, corners)
    rows = _point_rows(triangles[owner], bary, n)  # (P, N)
    weight = options.data_weight / len(points)
    gram = (rows.T @ rows) * weight
    blocks.append(sp.kron(gram, sp.identity(3), format="csr"))
    rhs += (rows.T @ points * weight).reshape(-1)
    energy += weight * float(np.sum((rows @ positions - points) ** 2))

    # mesh -> points: samples on the faces onto the nearest point's plane
    if options.face_weight > 0:
        sample_bary = _sample_weights(options.face_samples)  # (S0, 3)
        cols = np.repeat(triangles, len(sample_bary), axis=0)  # (T S0, 3)
        wts = np.tile(sample_bary, (len(triangles), 1))
        samples = np.einsum("mk,mkd->md", wts, positions[cols])
        _, nearest = tree.query(samples)
        plane = normals[nearest]
        planes = _plane_rows(cols, wts, plane, n)
        weight = options.face_weight / len(samples)
        target = np.einsum("md,md->m", plane, points[nearest])
        blocks.append((planes.T @ planes) * weight)
        rhs += planes.T @ target * weight
        energy += weight * float(np.sum((planes @ x - target) ** 2))

    # tangent planes of the points near each vertex (sharp features): the points
    # within about half the vertex's edge length, as dual contouring's cell
    if options.plane_weight > 0:
        k = int(min(options.plane_neighbours, len(points)))
        distance, near = tree.query(positions, k=k)
        distance, near = distance.reshape(n, k), near.reshape(n, k)
        reach = _vertex_reach(positions, edges) * options.plane_reach  # (N,)
        sigma2 = np.maximum(reach, distance[:, 0] + 1e-12)[:, None] ** 2  # (N, 1)
        gauss = np.exp(-(distance ** 2) / sigma2)  # (N, k)
        gauss /= gauss.sum(axis=1, keepdims=True)
        cols = np.repeat(np.arange(n), k)[:, None]
        plane = normals[near.reshape(-1)]
        planes = _plane_rows(cols, np.ones((n * k, 1)), plane, n)
        target = np.einsum("md,md->m", plane, points[near.reshape(-1)])
        weight = options.plane_weight / n * gauss.reshape(-1)
        weighted = sp.diags(weight) @ planes
        blocks.append(planes.T @ weighted)
        rhs += weighted.T @ target
        energy += float(np.sum(weight * (planes @ x - target) ** 2))

    # springs over the edges
    if options.spring_weight > 0 and len(edges):
        incidence = _incidence(edges, n)
        weight = options.spring_weight / len(edges)
        laplacian = (incidence.T @ incidence) * weight
        blocks.append(sp.kron(laplacian, sp.identity(3), format="csr"))
        energy += weight * float(np.sum((incidence @ positions) ** 2))

    matrix = blocks[0]
    for block in blocks[1:]:
        matrix = matrix + block
    return matrix.tocsr(), rhs, energy


def fit_vertices(
    positions: FloatArray,
    triangles: IntArray,
    points: FloatArray,
    normals: FloatArray | None = None,
    options: VertexFitOptions | None = None,
    fixed: BoolArray | None = None,
    noise: float | None = None,
) -> tuple[FloatArray, list[float]]:
    """Move the vertices to minimise the fit energy (see the module docstring).

    Parameters
    ----------
    positions : (N, 3) float
        Vertices of a triangle mesh (unused vertices stay where they are).
    triangles : (T, 3) int
    points : (P, 3) float
        Finite conditioning points, in the frame of ``positions``.
    normals : (P, 3) float, optional
        The points' normals (any sign); estimated when None.
    options : VertexFitOptions, optional
    fixed : (N,) bool, optional
        Vertices that keep their positions exactly (a repair's kept vertices); the
        solve is over the others only.
    noise : float, optional
        The points' noise for ``options.noise_spring`` (from :func:`plane_fits` when
        None; a caller fitting several times passes it once measured).

    Returns
    -------
    positions : (N, 3) float64
    energies : list of float
        The energy after each round's projection (before its solve).
    """
    options = options or VertexFitOptions()
    positions = np.asarray(positions, dtype=np.float64).copy()
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(triangles) == 0 or len(points) < 4:
        return positions, []
    if normals is None or (noise is None and options.noise_spring > 0):
        fitted, measured = plane_fits(points)
        noise = measured if noise is None else noise
        normals = fitted if normals is None else normals
    normals = np.asarray(normals, dtype=np.float64)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), 0.0)
    tree = cKDTree(points)
    used = np.zeros(len(positions), dtype=bool)
    used[triangles.reshape(-1)] = True
    free = used if fixed is None else used & ~np.asarray(fixed, dtype=bool)
    if options.noise_spring > 0:
        edges = _edges(triangles)
        length = float(np.mean(np.linalg.norm(
            positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)))
        assert noise is not None  # measured above when noise_spring > 0
        ratio = (float(noise) / length) ** 2 if length > 0 else 0.0
        options = replace(options, spring_weight=options.spring_weight
                          + options.noise_spring * ratio)
    unknown = np.repeat(free, 3)  # (3N,) coordinates that the solve moves
    energies = []
    for _ in range(options.iterations if free.any() else 0):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        matrix, rhs, energy = fit_energy_terms(positions, triangles, points, normals, tree,
                                               options)
        energies.append(energy)
        damping = options.damping / len(positions)
        x = positions.reshape(-1)
        # the others stay put: A_ff x_f = r_f - A_fc x_c (+ damping toward x_f)
        matrix = matrix.tocsr()
        if unknown.all():  # nothing held: the whole system (slicing it copies the same)
            block = matrix + sp.identity(len(unknown)) * damping
            known = np.zeros(len(unknown))
        else:
            block = matrix[unknown][:, unknown] + sp.identity(int(unknown.sum())) * damping
            known = matrix[unknown][:, ~unknown] @ x[~unknown]
        solution = spsolve(block.tocsc(), rhs[unknown] - known + damping * x[unknown])
        if not np.isfinite(solution).all():
            break
        x = x.copy()
        x[unknown] = solution
        positions = x.reshape(-1, 3)
    return positions, energies


# ---------------------------------------------------------------------- fitting to a mesh
#: Rounds of :func:`fit_to_surface` (closest points, then one linear solve, each).
FIT_ROUNDS = 3
#: Weight of the springs along the edges in :func:`fit_to_surface`, against one
#: surface sample of average area (keeps vertices no sample reaches in place, and the
#: tessellation even).
FIT_SPRING = 0.05
#: Samples per surface triangle in :func:`fit_to_surface`: the centroids of its
#: subdivision into this squared.
FIT_SAMPLE_LEVEL = 3


def fit_to_surface(positions: FloatArray, triangles: IntArray, moving: BoolArray,
                   surface_points: FloatArray, surface_triangles: IntArray,
                   rounds: int = FIT_ROUNDS, spring: float = FIT_SPRING) -> FloatArray:
    """Move the ``moving`` vertices so that the triangles best approximate a surface
    given as a mesh, in the least-squares sense, rather than interpolate it.

    Vertices laid onto a curved surface make chords that all fall on one side of it
    (a coarse patch on a dome sinks into it). This is the points -> mesh and spring
    terms of :func:`fit_vertices` (Hoppe et al. 1993), with the points spread evenly
    over the surface's triangles and weighted by their area: each round finds every
    sample's closest point and its barycentric coordinates, then solves the linear
    least-squares problem for the positions. No tangent planes: the surface is known,
    and its planes would pull the vertices back onto it.

    Parameters
    ----------
    positions : (V, 3) float
    triangles : (T, 3) int
        The triangles fitted (the other vertices they use stay fixed).
    moving : (V,) bool
    surface_points : (P, 3) float
    surface_triangles : (S, 3) int
        The surface approximated.
    rounds : int
    spring : float
        :data:`FIT_SPRING`.

    Returns
    -------
    (V, 3) float64
    """
    x = np.asarray(positions, dtype=np.float64).copy()
    rows = np.flatnonzero(moving)
    if len(rows) == 0 or len(triangles) == 0 or len(surface_triangles) == 0:
        return x
    corners = surface_points[surface_triangles]  # (S, 3, 3)
    weights = _subtriangle_centroids(FIT_SAMPLE_LEVEL)  # (G, 3)
    samples = np.einsum("gk,skd->sgd", weights, corners).reshape(-1, 3)  # (S G, 3)
    area = triangle_areas(surface_points, surface_triangles)  # (S,)
    mass = np.repeat(area, len(weights))
    mass = mass / max(float(mass.mean()), 1e-300)  # (S G,), mean 1
    n = len(x)
    incidence = _incidence(_edges(triangles), n)
    springs = spring * (incidence.T @ incidence)  # (V, V)
    fixed = ~moving
    for _ in range(rounds):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        owner, _, closest = nearest_points(samples, x, triangles)
        under = x[triangles[owner]]  # (M, 3, 3)
        bary = barycentric(closest, under)  # (M, 3)
        basis = _point_rows(triangles[owner], bary, n)  # (M, V)
        weighted = sp.diags(mass) @ basis
        normal = (basis.T @ weighted + springs).tocsr()
        rhs = weighted.T @ samples  # (V, 3)
        a = normal[rows][:, rows].tocsc()
        b = rhs[rows] - normal[rows][:, fixed] @ x[fixed]
        solved = np.asarray(spsolve(a, b)).reshape(len(rows), 3)
        if not np.isfinite(solved).all():
            break
        x[rows] = solved
    return x
