"""Laying a patch onto another fill's surface: the patch keeps its tessellation (the
model's), and its own vertices move onto the surface of the fill the probes or the
fairing trust more (the faired fan, the flat fill), guarded against folds, collapsed
faces and new self-intersections (:func:`lay_onto`).

numpy and scipy only.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import identity

from spacemesh.cancel import checkpoint
from spacemesh.geometry.fitting import fit_to_surface
from spacemesh.geometry.intersections import self_intersecting_faces
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import faces_subset, faces_touching, triangulate_faces, vertices_of
from spacemesh.primitives.closest import nearest_points, nearest_triangles
from spacemesh.repair.fill.laplace import laplacian
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Cosine below which a face of the model's patch, laid onto the faired fan's surface
#: (:func:`spacemesh.repair.fill.finish.onto_fan`), counts as folded over against the fan
#: face under it.
MIN_FOLD_COSINE = 0.2
#: Share of its mean triangle area below which a laid-on face counts as collapsed.
MIN_AREA_SHARE = 0.02
#: Rounds of tangential relaxation (each vertex to the mean of its neighbours, laid
#: back onto the fan) tried on a laid-on patch with a folded or collapsed face: the
#: default of :attr:`spacemesh.repair.fill.policy.FillPolicy.relax_rounds`.
RELAX_ROUNDS = 5


def badly_laid(positions: FloatArray, triangles: IntArray, fan_points: FloatArray,
                fan_triangles: IntArray) -> bool:
    """Whether a triangle ``triangles`` (P, 3) at ``positions`` folds over against the
    fan triangle under its centre (cosine below :data:`MIN_FOLD_COSINE`) or collapses
    (area below :data:`MIN_AREA_SHARE` of the mean)."""
    if len(triangles) == 0:
        return False
    corners = positions[triangles]  # (P, 3, 3)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(normal, axis=1)  # (P,)
    owner, _ = nearest_triangles(corners.mean(axis=1), fan_points, fan_triangles)
    under = fan_points[fan_triangles[owner]]  # (P, 3, 3)
    fan_normal = np.cross(under[:, 1] - under[:, 0], under[:, 2] - under[:, 0])
    cosine = np.einsum("ij,ij->i", normal, fan_normal) / np.maximum(
        np.linalg.norm(normal, axis=1) * np.linalg.norm(fan_normal, axis=1), 1e-300)
    return bool(cosine.min() < MIN_FOLD_COSINE or area.min() < MIN_AREA_SHARE * area.mean())


def lay_onto(mesh: PolygonMesh, patch: BoolArray, surface_points: FloatArray,
             surface_triangles: IntArray, *, fit: bool = False,
             relax_rounds: int = RELAX_ROUNDS) -> FloatArray | None:
    """The positions of ``mesh`` with the own vertices of the ``patch`` faces ((F,) bool;
    those no other face uses) moved to their closest points on the triangles
    ``surface_triangles`` (T, 3) over ``surface_points`` (P, 3); None where that folds a
    face over or collapses one (:func:`badly_laid`) even after ``relax_rounds`` rounds
    of tangential relaxation (each vertex to the mean of its neighbours, laid back on
    the surface), or adds a self-intersection near the patch. With ``fit``
    (:attr:`spacemesh.repair.fill.policy.FillPolicy.fit_laid`), the laid vertices then
    move so that the patch approximates the surface in the least-squares sense rather
    than interpolating it (:func:`spacemesh.geometry.fitting.fit_to_surface`: a coarse
    patch laid on a dome otherwise sinks into it), kept where that folds or collapses no face."""
    moving = vertices_of(mesh, patch) & ~vertices_of(mesh, ~patch)
    rows = np.flatnonzero(moving)

    def laid(points: FloatArray) -> FloatArray:
        return nearest_points(points, surface_points, surface_triangles)[2]

    positions = mesh.vertices.copy()
    if len(rows):
        positions[rows] = laid(positions[rows])
    triangles, _ = triangulate_faces(faces_subset(mesh, patch))
    average = identity(mesh.n_vertices, format="csr") - laplacian(mesh, patch, uniform=True)
    bad = badly_laid(positions, triangles, surface_points, surface_triangles)
    for _ in range(relax_rounds if len(rows) else 0):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        if not bad:
            break
        positions[rows] = laid((average @ positions)[rows])
        bad = badly_laid(positions, triangles, surface_points, surface_triangles)
    if bad:
        return None
    if fit and len(rows):
        fitted = fit_to_surface(positions, triangles, moving, surface_points,
                                surface_triangles)
        if not badly_laid(fitted, triangles, surface_points, surface_triangles):
            positions = fitted
    near = faces_touching(mesh, vertices_of(mesh, faces_touching(mesh, moving)))
    before = int(self_intersecting_faces(faces_subset(mesh, near)).sum())
    after = int(self_intersecting_faces(faces_subset(mesh.with_vertices(positions),
                                                      near)).sum())
    return None if after > before else positions
