"""Synthetic stress cases for fitting: high-degree vertices, needle triangles, big n-gons.

Low-poly models (3D printing, CAD) have what the smooth meshes of a dataset rarely have:
vertices of degree 20 to 100 (fans, cones, poles), long thin triangles and faces of 30
or more sides. Each builder returns a closed oriented manifold :class:`PolygonMesh`;
:data:`STRESS_CASES` names a set of them for ``experiments/fit_stress.py``, the tests and
docs/fitting/.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from spacemesh.examples import prism
from spacemesh.mesh import PolygonMesh


def _ring(n: int, z: float = 0.0, radius: float = 1.0) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full(n, z)], 1)


def pyramid(n: int, height: float = 1.0) -> PolygonMesh:
    """An n-gon base and ``n`` triangles meeting at an apex of degree ``n``.

    Parameters
    ----------
    n : int
        Base sides (at least 3).
    height : float
        Apex height; large values make needle triangles.

    Returns
    -------
    PolygonMesh
        ``n + 1`` vertices, ``n + 1`` faces.
    """
    v = np.concatenate([_ring(n), [[0.0, 0.0, height]]])
    faces = [list(range(n))[::-1]] + [[i, (i + 1) % n, n] for i in range(n)]
    return PolygonMesh.from_faces(v, faces)


def bipyramid(n: int, height: float = 1.0) -> PolygonMesh:
    """Two apexes of degree ``n`` over a ring of ``n`` vertices: ``2n`` triangles."""
    v = np.concatenate([_ring(n), [[0.0, 0.0, height], [0.0, 0.0, -height]]])
    faces = [[i, (i + 1) % n, n] for i in range(n)]
    faces += [[(i + 1) % n, i, n + 1] for i in range(n)]
    return PolygonMesh.from_faces(v, faces)


def fan_prism(n: int) -> PolygonMesh:
    """An n-gon prism whose caps are fan-triangulated from one vertex each.

    The fan vertices have degree ``n`` and the fans are needle triangles (the ones
    next to the fan vertex are long and thin).
    """
    base = prism(n)
    v = base.vertices
    faces = [[0, i + 1, i] for i in range(1, n - 1)]
    faces += [[n, n + i, n + i + 1] for i in range(1, n - 1)]
    faces += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return PolygonMesh.from_faces(v, faces)


def capped_cylinder(n: int, height: float = 1.0) -> PolygonMesh:
    """A cylinder of ``n`` quads whose caps are triangle fans from a centre vertex each.

    The two centres have degree ``n`` and no neighbour in common: the CAD pattern (a
    round boss or hole) that is slowest to fit, since both hubs must be near all of their
    own ring and far from each other.
    """
    v = np.concatenate([_ring(n), _ring(n, height), [[0.0, 0.0, 0.0], [0.0, 0.0, height]]])
    bottom, top = 2 * n, 2 * n + 1
    faces = [[(i + 1) % n, i, bottom] for i in range(n)]
    faces += [[n + i, n + (i + 1) % n, top] for i in range(n)]
    faces += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return PolygonMesh.from_faces(v, faces)


def uv_sphere(n_lon: int, n_lat: int) -> PolygonMesh:
    """A latitude-longitude sphere: quads, and two poles of degree ``n_lon`` with
    triangle fans (needles near the poles when ``n_lon`` is large)."""
    lat = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    rings = [_ring(n_lon, np.cos(t), np.sin(t)) for t in lat]
    v = np.concatenate([*rings, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
    top, bottom = len(v) - 2, len(v) - 1

    def idx(r: int, i: int) -> int:
        return r * n_lon + i % n_lon

    faces = [[idx(0, i), idx(0, i + 1), top] for i in range(n_lon)]
    for r in range(n_lat - 2):
        faces += [[idx(r, i), idx(r, i + 1), idx(r + 1, i + 1), idx(r + 1, i)][::-1]
                  for i in range(n_lon)]
    last = n_lat - 2
    faces += [[idx(last, i + 1), idx(last, i), bottom] for i in range(n_lon)]
    return PolygonMesh.from_faces(v, faces)


def hub_ring(k: int, m: int) -> PolygonMesh:
    """A thick washer whose flat faces join a coarse outer ring to a fine inner one.

    The outer rings have ``k`` vertices, the inner ones ``k * m``; each outer vertex fans
    over ``m + 1`` inner ones (long thin triangles), so all ``2k`` outer vertices are hubs
    of degree ``m + 4``, each adjacent to three others: the CAD pattern of a coarse
    boundary tessellated against a fine circle, with many hubs next to each other.
    Quads close the outer wall and the inner tube (genus 1).
    """
    n_in = k * m
    outer = [_ring(k, 0.0, 2.0), _ring(k, 1.0, 2.0)]
    inner = [_ring(n_in, 0.0, 1.0), _ring(n_in, 1.0, 1.0)]
    v = np.concatenate([*outer, *inner])

    def o(level: int, i: int) -> int:
        return level * k + i % k

    def c(level: int, j: int) -> int:
        return 2 * k + level * n_in + j % n_in

    faces = []
    for level, flip in ((1, False), (0, True)):  # top faces +z, bottom faces -z
        for i in range(k):
            fan = [[c(level, j), o(level, i), c(level, j + 1)] for j in range(i * m, (i + 1) * m)]
            fan.append([o(level, i), o(level, i + 1), c(level, (i + 1) * m)])
            faces += [f[::-1] for f in fan] if flip else fan
    faces += [[o(0, i), o(0, i + 1), o(1, i + 1), o(1, i)] for i in range(k)]
    faces += [[c(0, j), c(1, j), c(1, j + 1), c(0, j + 1)] for j in range(n_in)]
    return PolygonMesh.from_faces(v, faces)


#: Named stress cases: the highest vertex degree and the largest face of each.
STRESS_CASES: dict[str, Callable[[], PolygonMesh]] = {
    "pyramid over a 30-gon": lambda: pyramid(30),
    "pyramid over a 60-gon": lambda: pyramid(60),
    "pyramid over a 100-gon": lambda: pyramid(100),
    "needle bipyramid, degree 40": lambda: bipyramid(40, height=20.0),
    "bipyramid, degree 100": lambda: bipyramid(100),
    "prism of 40-gons": lambda: prism(40),
    "fan-capped prism, degree 40": lambda: fan_prism(40),
    "fan-capped prism, degree 80": lambda: fan_prism(80),
    "uv sphere, poles of degree 64": lambda: uv_sphere(64, 12),
    "capped cylinder, hubs of degree 40": lambda: capped_cylinder(40),
    "capped cylinder, hubs of degree 126": lambda: capped_cylinder(126),
    "hub ring, 16 adjacent hubs of degree 36": lambda: hub_ring(8, 32),
    "hub ring, 12 adjacent hubs of degree 64": lambda: hub_ring(6, 60),
}
