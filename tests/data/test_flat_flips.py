"""The qem style's flat flips: coplanar quads take their Delaunay diagonal, nothing moves."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.data.styles import delaunay_flip_flat

pymeshlab = pytest.importorskip("pymeshlab")


def _badly_triangulated_grid(size: int = 7, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A flat jittered grid whose quads are split along their longer diagonal."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.arange(size, dtype=float), np.arange(size, dtype=float))
    points = np.stack([u.ravel(), v.ravel(), np.zeros(size * size)], axis=1)
    interior = (points[:, 0] % (size - 1) != 0) & (points[:, 1] % (size - 1) != 0)
    points[interior, :2] += rng.uniform(-0.3, 0.3, (int(interior.sum()), 2))
    triangles = []
    for row in range(size - 1):
        for col in range(size - 1):
            a, b = row * size + col, row * size + col + 1
            c, d = b + size, a + size
            if np.linalg.norm(points[a] - points[c]) > np.linalg.norm(points[b] - points[d]):
                triangles += [[a, b, c], [a, c, d]]
            else:
                triangles += [[a, b, d], [b, c, d]]
    return points, np.asarray(triangles, dtype=np.int32)


def _non_delaunay_interior_edges(points: np.ndarray, triangles: np.ndarray) -> int:
    """Interior edges whose two opposite angles sum to more than pi."""
    opposite: dict[tuple[int, int], list[int]] = {}
    for tri in triangles.tolist():
        for k in range(3):
            a, b, c = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            opposite.setdefault((min(a, b), max(a, b)), []).append(c)

    def angle(at: int, a: int, b: int) -> float:
        p, q = points[a] - points[at], points[b] - points[at]
        return float(np.arccos(np.clip(p @ q / np.linalg.norm(p) / np.linalg.norm(q), -1, 1)))

    return sum(
        angle(o[0], a, b) + angle(o[1], a, b) > np.pi + 1e-9
        for (a, b), o in opposite.items() if len(o) == 2
    )


def test_flat_flips_make_every_interior_edge_delaunay_and_keep_the_vertices():
    points, triangles = _badly_triangulated_grid()
    before = _non_delaunay_interior_edges(points, triangles)
    assert before >= 10
    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=points, face_matrix=triangles))
    delaunay_flip_flat(meshset)
    flipped = meshset.current_mesh()
    assert np.array_equal(flipped.vertex_matrix(), points)
    faces = flipped.face_matrix()
    assert len(faces) == len(triangles)
    assert _non_delaunay_interior_edges(points, faces) == 0
    # same orientation (all normals still +z)
    normals = np.cross(points[faces[:, 1]] - points[faces[:, 0]],
                       points[faces[:, 2]] - points[faces[:, 0]])
    assert (normals[:, 2] > 0).all()
    directed = [(f[k], f[(k + 1) % 3]) for f in faces.tolist() for k in range(3)]
    assert len(set(directed)) == len(directed)  # each directed edge once: oriented manifold


def test_twisted_quads_are_not_flipped():
    # the same grid on a saddle z = 0.3 (x - 3)(y - 3): every quad is folded by degrees
    points, triangles = _badly_triangulated_grid(seed=1)
    twisted = points.copy()
    twisted[:, 2] = 0.3 * (points[:, 0] - 3.0) * (points[:, 1] - 3.0)
    meshset = pymeshlab.MeshSet()
    meshset.add_mesh(pymeshlab.Mesh(vertex_matrix=twisted, face_matrix=triangles))
    delaunay_flip_flat(meshset)
    faces = meshset.current_mesh().face_matrix()
    assert sorted(map(tuple, np.sort(faces, axis=1).tolist())) == sorted(
        map(tuple, np.sort(triangles, axis=1).tolist()))
    assert _non_delaunay_interior_edges(points, triangles) > 0  # flat, it would flip
