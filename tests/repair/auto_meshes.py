"""Meshes with holes and defects for the automatic-region tests (repair, CLI, service)."""

from __future__ import annotations

import numpy as np

from spacemesh.examples import icosphere
from spacemesh.mesh import PolygonMesh
from spacemesh.repair.patch import sub_mesh


def without_faces(mesh: PolygonMesh, drop: np.ndarray) -> PolygonMesh:
    """``mesh`` without the faces ``drop`` ((F,) bool) and the vertices only they used."""
    return sub_mesh(mesh, np.flatnonzero(~drop)).remove_unreferenced_vertices()[0]


def punched(mesh: PolygonMesh, centres: list[list[float]], radius: float = 0.25
            ) -> PolygonMesh:
    """``mesh`` with a hole around each centre: the faces with a vertex within ``radius``
    removed."""
    d = np.linalg.norm(mesh.vertices[:, None] - np.asarray(centres, float)[None], axis=2)
    near = d.min(axis=1) < radius
    drop = np.zeros(mesh.n_faces, dtype=bool)
    drop[mesh.face_of_corner[near[mesh.face_indices]]] = True
    return without_faces(mesh, drop)


def hemisphere(subdivisions: int = 4) -> PolygonMesh:
    """The lower half of an icosphere: one large open loop."""
    mesh = icosphere(subdivisions)
    drop = np.zeros(mesh.n_faces, dtype=bool)
    drop[mesh.face_of_corner[(mesh.vertices[:, 2] > 0.0)[mesh.face_indices]]] = True
    return without_faces(mesh, drop)


def moebius(n: int = 12, width: float = 0.3) -> PolygonMesh:
    """A Moebius strip of ``n`` quads (not orientable)."""
    verts = []
    for a in np.linspace(0, 2 * np.pi, n, endpoint=False):
        for s in (-width, width):
            r = 1 + s * np.cos(a / 2)
            verts.append([r * np.cos(a), r * np.sin(a), s * np.sin(a / 2)])
    faces = [[2 * i, 2 * (i + 1), 2 * (i + 1) + 1, 2 * i + 1] for i in range(n - 1)]
    faces.append([2 * (n - 1), 1, 0, 2 * (n - 1) + 1])  # the half twist
    return PolygonMesh.from_faces(np.asarray(verts), faces)


def with_fin(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` plus a triangle on the first edge of face 0 (a non-manifold edge)."""
    a, b = mesh.faces[0][:2]
    vertices = np.vstack([mesh.vertices, 2.0 * mesh.vertices[a]])
    return PolygonMesh.from_faces(vertices, [*mesh.faces, np.array([a, b, len(vertices) - 1])])


def with_degenerate_face(mesh: PolygonMesh) -> PolygonMesh:
    """``mesh`` plus a face visiting a vertex twice."""
    a, b = mesh.faces[0][:2]
    return PolygonMesh.from_faces(mesh.vertices, [*mesh.faces, np.array([a, b, a])])


def pinched_spheres() -> PolygonMesh:
    """Two icospheres sharing one vertex (a non-manifold vertex)."""
    ico = icosphere(1)
    top, bottom = int(np.argmax(ico.vertices[:, 2])), int(np.argmin(ico.vertices[:, 2]))
    second = np.arange(ico.n_vertices) + ico.n_vertices
    second[bottom] = top
    lifted = ico.vertices + np.array([0.0, 0.0, 2.0])
    mesh = PolygonMesh.from_faces(np.vstack([ico.vertices, lifted]),
                                  ico.faces + [second[f] for f in ico.faces])
    return mesh.remove_unreferenced_vertices()[0]


def grid_disk(n: int = 6) -> PolygonMesh:
    """A flat ``(n - 1) x (n - 1)`` quad grid: an open disk."""
    verts = [[x, y, 0.0] for y in range(n) for x in range(n)]
    faces = [[y * n + x, y * n + x + 1, (y + 1) * n + x + 1, (y + 1) * n + x]
             for y in range(n - 1) for x in range(n - 1)]
    return PolygonMesh.from_faces(np.asarray(verts, float), faces)


def cylinder(around: int = 24, rows: int = 12, height: float = 2.0) -> PolygonMesh:
    """A closed triangulated unit-radius cylinder along z (side rows, fans at the caps)."""
    angle = 2 * np.pi * np.arange(around) / around
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    z = np.linspace(-height / 2, height / 2, rows + 1)
    verts = [[x, y, h] for h in z for x, y in ring] + [[0, 0, z[0]], [0, 0, z[-1]]]
    bottom, top = len(verts) - 2, len(verts) - 1
    faces = []
    for r in range(rows):
        for i in range(around):
            a, b = r * around + i, r * around + (i + 1) % around
            faces += [[a, b, b + around], [a, b + around, a + around]]
    for i in range(around):
        faces.append([bottom, (i + 1) % around, i])
        faces.append([top, rows * around + i, rows * around + (i + 1) % around])
    return PolygonMesh.from_faces(np.asarray(verts, float), faces)


def _rings(mesh: PolygonMesh, v: int) -> tuple[set[int], list[set[int]]]:
    """The neighbours of ``v`` and the vertex sets of the faces around it."""
    faces = [set(f.tolist()) for f in mesh.faces]
    around = [f for f in faces if v in f]
    return set().union(*around) - {v}, around


def touching_holes() -> PolygonMesh:
    """An icosphere with two holes (the fans of two vertices removed) whose loops touch
    at one vertex: two loops through it, between two fans of faces."""
    mesh = icosphere(2)
    faces = [set(f.tolist()) for f in mesh.faces]
    for a in range(mesh.n_vertices):
        ring_a, _ = _rings(mesh, a)
        for c in sorted(ring_a):
            ring_c, _ = _rings(mesh, c)
            for b in sorted(ring_c - ring_a - {a}):
                ring_b, _ = _rings(mesh, b)
                if ring_a & ring_b != {c}:
                    continue
                drop = np.array([a in f or b in f for f in faces])
                kept_at_c = [f for f, d in zip(faces, drop, strict=True) if c in f and not d]
                if len(kept_at_c) == 2 and not (kept_at_c[0] & kept_at_c[1]) - {c}:
                    return without_faces(mesh, drop)
    raise AssertionError("no pair of vertices opposite across a third")


def pinched_annulus() -> PolygonMesh:
    """An icosphere with an annular hole whose island (the fan of a vertex) still
    touches the rest at one vertex: one loop that passes that vertex twice."""
    mesh = icosphere(2)
    a = 0
    ring1, _ = _rings(mesh, a)
    faces = [set(f.tolist()) for f in mesh.faces]
    c = min(ring1)
    outer = [k for k, f in enumerate(faces) if c in f and not (f - {c}) & (ring1 | {a})]
    drop = np.array([bool(f & ring1) and a not in f for f in faces])
    drop[outer[0]] = False  # the one face that ties the island's corner to the rest
    return without_faces(mesh, drop)
