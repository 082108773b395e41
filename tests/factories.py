"""Small meshes made in code: tests never read ../shared/meshes."""

from __future__ import annotations

import numpy as np
from spacemesh.mesh import PolygonMesh


def cube_quads() -> PolygonMesh:
    """A unit cube of six outward quads."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return PolygonMesh.from_faces(v, faces)


def icosphere(subdivisions: int = 1) -> PolygonMesh:
    """A triangulated sphere."""
    import trimesh

    t = trimesh.creation.icosphere(subdivisions)
    return PolygonMesh.from_faces(t.vertices, t.faces)


def torus_grid(n_major: int = 12, n_minor: int = 8, triangulate_every: int = 0) -> PolygonMesh:
    """A quad torus (genus 1); optionally split every k-th quad into two triangles."""
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


def prism(n: int = 5) -> PolygonMesh:
    """An n-gon prism: two n-gon caps and n quads."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], 1)
    v = np.concatenate([np.c_[ring, np.zeros(n)], np.c_[ring, np.ones(n)]])
    faces = [list(range(n))[::-1], list(range(n, 2 * n))]
    faces += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return PolygonMesh.from_faces(v, faces)
