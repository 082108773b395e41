"""Small example meshes made in code: a quad cube, an n-gon prism, a mixed torus, a sphere.

Used by the README's first command, the tests and the benchmarks, so that nothing
depends on third-party mesh files.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh


def cube_quads(size: float = 1.0) -> PolygonMesh:
    """A cube of six outward quads with edge length ``size``."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return PolygonMesh.from_faces(v * size, faces)


def prism(n: int = 5) -> PolygonMesh:
    """An n-gon prism: two n-gon caps and n quads, oriented outward."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], 1)
    v = np.concatenate([np.c_[ring, np.zeros(n)], np.c_[ring, np.ones(n)]])
    faces = [list(range(n))[::-1], list(range(n, 2 * n))]
    faces += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return PolygonMesh.from_faces(v, faces)


def torus_grid(n_major: int = 12, n_minor: int = 8, triangulate_every: int = 0) -> PolygonMesh:
    """A quad torus (genus 1), oriented outward.

    Parameters
    ----------
    n_major, n_minor : int
        Segments around the two circles (``n_major * n_minor`` vertices).
    triangulate_every : int
        Split every k-th quad into two triangles (0: none), for mixed meshes.

    Returns
    -------
    PolygonMesh
    """
    u = np.linspace(0, 2 * np.pi, n_major, endpoint=False)
    w = np.linspace(0, 2 * np.pi, n_minor, endpoint=False)
    uu, ww = np.meshgrid(u, w, indexing="ij")
    v = np.stack(
        [(2 + np.cos(ww)) * np.cos(uu), (2 + np.cos(ww)) * np.sin(uu), np.sin(ww)], -1
    ).reshape(-1, 3)

    def idx(i: int, j: int) -> int:
        return (i % n_major) * n_minor + (j % n_minor)

    faces = []
    for i in range(n_major):
        for j in range(n_minor):
            quad = [idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]
            if triangulate_every and (i * n_minor + j) % triangulate_every == 0:
                faces += [quad[:3], [quad[0], quad[2], quad[3]]]
            else:
                faces.append(quad)
    return PolygonMesh.from_faces(v, faces)


def icosphere(subdivisions: int = 2) -> PolygonMesh:
    """A triangulated unit sphere: 12 vertices, each subdivision about quadruples them."""
    t = (1 + 5**0.5) / 2
    v = np.array(
        [
            [-1, t, 0],
            [1, t, 0],
            [-1, -t, 0],
            [1, -t, 0],
            [0, -1, t],
            [0, 1, t],
            [0, -1, -t],
            [0, 1, -t],
            [t, 0, -1],
            [t, 0, 1],
            [-t, 0, -1],
            [-t, 0, 1],
        ],
        float,
    )
    f = np.array(
        [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ]
    )
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = len(v) + inverse.reshape(3, -1).T  # (F, 3): midpoints of edges 01, 12, 20
        v = np.concatenate([v, v[unique].mean(axis=1)])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate(
            [np.stack(x, 1) for x in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])]
        )
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return PolygonMesh.from_faces(v, f)


EXAMPLES = {
    "cube": cube_quads,
    "prism": lambda: prism(6),
    "torus": lambda: torus_grid(24, 12, triangulate_every=5),
    "sphere": lambda: icosphere(3),
}
