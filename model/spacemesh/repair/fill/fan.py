"""The fan fill: each loop closed by a fan of triangles from a new vertex at its
centroid (:func:`fan_fill`), the start of a region filled in place and of the fairing's
probe fills, and the fan refined and faired hole by hole (:func:`faired_fan`), which
replaces a patch the fairing could not move all the way.

numpy only (the fairing: numpy and scipy).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset
from spacemesh.repair.fill.loops import patch_edge_length, patch_loops, patch_parts
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.typed import BoolArray, IntArray


def fan_fill(mesh: PolygonMesh, loops: list[IntArray]) -> tuple[PolygonMesh, list[IntArray]]:
    """Close each loop by a fan of triangles from a new vertex at its centroid.

    Returns
    -------
    mesh : PolygonMesh
        ``mesh``'s vertices then the centroids; its faces then the fans.
    fans : list of (L,) int64
        The new faces of each loop (in loop order).
    """
    centroids = np.array([mesh.vertices[loop].mean(axis=0) for loop in loops]).reshape(-1, 3)
    faces, fans, next_face = [], [], mesh.n_faces
    for c, loop in enumerate(loops):
        centre = mesh.n_vertices + c
        faces += [[int(a), int(b), centre] for a, b in zip(loop, np.roll(loop, -1), strict=True)]
        fans.append(np.arange(next_face, next_face + len(loop)))
        next_face += len(loop)
    sizes = np.concatenate([mesh.face_sizes, np.full(len(faces), 3)])
    indices = np.concatenate([mesh.face_indices, np.asarray(faces, np.int64).reshape(-1)])
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    return PolygonMesh(np.concatenate([mesh.vertices, centroids]), indices, offsets), fans


def faired_fan(mesh: PolygonMesh, patch: BoolArray, policy: FillPolicy
               ) -> tuple[PolygonMesh, IntArray, BoolArray] | None:
    """A fan over each loop of the ``patch`` faces ((F,) bool) of ``mesh``
    (:func:`fan_fill`), refined and faired (the ``policy``'s fairing,
    :func:`spacemesh.repair.fill.fairing.fair_patch`) one hole (one part of the patch,
    :func:`~spacemesh.repair.fill.loops.patch_parts`) after the other, so that each
    hole's fairing reads its own surroundings, with the patch's faces left out.

    Returns the faired mesh (``mesh``'s vertices first, then the fans'), the face of
    ``mesh`` each of its faces is (-1: the fans'), and its fan faces; None without
    loops, or where a fan could not be faired all the way (a self-intersection held it
    back) or only flat (one of the policy's
    :attr:`~spacemesh.repair.fill.policy.FillPolicy.meshfix_fairings`).
    """
    found = [patch_loops(mesh, part) for part in patch_parts(mesh, patch)]
    parts = [loops for loops in found if loops]
    if not found or len(parts) != len(found):
        return None
    current = faces_subset(mesh, ~patch)  # mesh's vertices, the faces kept
    source = np.flatnonzero(~patch)  # (F_current,) face of mesh
    for loops in parts:
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        filled, _ = fan_fill(current, loops)  # current's vertices, then one centroid a loop
        fan = np.arange(filled.n_faces) >= current.n_faces
        free = np.arange(filled.n_vertices) >= current.n_vertices
        report: dict[str, Any] = {}
        current_faces = current.n_faces
        current, step, _ = policy.fair(filled, fan, free, patch_edge_length(filled, fan),
                                       report=report)
        if (report.get("weight", 0.0) < 1.0
                or report.get("fairing") in policy.meshfix_fairings):
            return None
        kept = (step >= 0) & (step < current_faces)
        source = np.where(kept, source[np.where(kept, step, 0)], -1)
    return current, source, source < 0
