"""Choosing a hole's fill by filling probe holes punched nearby, where the surface is
known: a local cross-validation of the fills an automatic region of holes can take.

Whether the fairing's patch (:func:`spacemesh.repair.fill.fairing.fair_patch`) or MeshFix's
fill (:func:`spacemesh.repair.fill.meshfix.meshfix_fill`) continues a surface better
depends on the surface: a thin plate continues smooth, curved surfaces, while over
creases, rims and coarse low-poly surfaces MeshFix's refined least-area fill often lies
closer. Neither the hole's own surface nor the intact mesh is known, but the surface
around the hole is. So, as the evaluation punches holes in intact meshes, a few **probe
holes** of the same size are punched in the input faces around the hole
(:func:`probe_regions`), each is filled by both methods on its own, and each fill is
scored against the faces it replaced (:func:`fill_error`). MeshFix's fill is taken for
the real hole only when it is clearly closer on the probes (the policy's
``meshfix_margin``, :func:`preferred_fill`). The least-area flat triangulation of the
loop is weighed the same way (``probe_margin``; the policy's ``alternatives``,
:data:`ALTERNATIVES`).

numpy and scipy (plus the optional ``pymeshfix`` that MeshFix's fill needs); nothing
here changes the mesh it is given.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.cancel import checkpoint
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import (
    faces_subset,
    faces_touching,
    triangulate_faces,
    unit_rows,
    vertices_of,
)
from spacemesh.primitives.closest import closest_points_on_triangles
from spacemesh.repair.fill.fan import fan_fill
from spacemesh.repair.fill.flat import flat_surface
from spacemesh.repair.fill.kinds import FillKind
from spacemesh.repair.fill.loops import patch_edge_length, patch_loops
from spacemesh.repair.fill.meshfix import faces_around
from spacemesh.repair.fill.policy import DEFAULT_POLICY, FillPolicy
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Probe holes punched around a hole.
PROBES = 4
#: Rings of faces around a probe handed to the fills (enough for the fairing's ring and
#: MeshFix's five rings).
PROBE_RINGS = 6
#: Points per triangle side of the barycentric grids the errors are measured on.
GRID_STEPS = 4
#: Nearest triangles (by centroid) searched for each point's closest point.
NEAREST_TRIANGLES = 8


def _grid(corners: FloatArray, steps: int = GRID_STEPS) -> tuple[FloatArray, FloatArray]:
    """Points on a barycentric grid of each triangle ``corners`` (T, 3, 3), and each
    point's weight (its triangle's area over the grid's size): (T * G, 3), (T * G,)."""
    i, j = np.meshgrid(np.arange(steps + 1), np.arange(steps + 1), indexing="ij")
    keep = i + j <= steps
    a, b = i[keep] / steps, j[keep] / steps
    bary = np.stack([1 - a - b, a, b], axis=1)  # (G, 3)
    points = np.einsum("gk,tkd->tgd", bary, corners).reshape(-1, 3)
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1)  # (T,)
    return points, np.repeat(area / len(bary), len(bary))


def surface_distance(points: FloatArray, corners: FloatArray) -> FloatArray:
    """Distance of each point (N, 3) to the triangles ``corners`` (T, 3, 3): the closest
    point among the :data:`NEAREST_TRIANGLES` triangles whose centroids are nearest, (N,)."""
    k = min(NEAREST_TRIANGLES, len(corners))
    _, nearest = cKDTree(corners.mean(axis=1)).query(points, k=k)
    nearest = np.asarray(nearest).reshape(len(points), k)  # (N, k)
    repeated = np.repeat(points, k, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):  # slivers: their sides decide
        closest = closest_points_on_triangles(repeated, corners[nearest.reshape(-1)])
    distance = np.linalg.norm(closest - repeated, axis=1).reshape(-1, k)
    return np.where(np.isfinite(distance), distance, np.inf).min(axis=1)


def fill_error(truth: FloatArray, fill: FloatArray) -> float:
    """Two-sided mean squared distance between the triangles ``truth`` (T, 3, 3) that a
    probe removed and a fill's triangles ``fill`` (S, 3, 3), each side weighted by area."""
    if len(truth) == 0 or len(fill) == 0:
        return float("inf")
    total = 0.0
    for source, target in ((truth, fill), (fill, truth)):
        points, weight = _grid(source)
        d = surface_distance(points, target)
        total += float(np.sum(weight * d**2) / max(float(np.sum(weight)), 1e-300))
    return total


#: A probe may hold edges this much sharper (degrees) than the sharpest edge around the
#: hole: a probe across a rim or crease the hole does not have would judge the fills on
#: a surface unlike the hole's.
SHARPNESS_TOLERANCE = 15.0
#: Rings of faces beyond the faces touching the hole whose edges give its sharpness.
SHARPNESS_RINGS = 1


def sharpest_edge(mesh: PolygonMesh, faces: BoolArray) -> float:
    """The largest dihedral angle (degrees, 0 for coplanar faces) over the edges joining
    two of the ``faces`` ((F,) bool), with polygon normals by Newell's formula; 0 without
    such an edge.

    Only the faces at the vertices of ``faces`` are read (every side of their edges is
    one of those faces'), unless a side there is shared by two faces (the twin the
    whole mesh's lookup picks is then read from the whole mesh, as it always was)."""
    around = faces_touching(mesh, vertices_of(mesh, faces))
    local = _sharpest_edge(faces_subset(mesh, around), faces[around], unique_twins=True)
    if local is not None:
        return local
    whole = _sharpest_edge(mesh, faces)  # never None without ``unique_twins``
    assert whole is not None
    return whole


def _sharpest_edge(mesh: PolygonMesh, faces: BoolArray, unique_twins: bool = False
                   ) -> float | None:
    """:func:`sharpest_edge` over every face of ``mesh``; with ``unique_twins``, None
    where the twin of a side of ``faces`` is not unique."""
    he = mesh.halfedges  # (H, 2)
    p = mesh.vertices
    inside = faces[mesh.face_of_corner]
    n = max(mesh.n_vertices, 1)
    key = he[:, 0] * n + he[:, 1]
    order = np.argsort(key)
    twin_key = he[:, 1] * n + he[:, 0]
    at = np.searchsorted(key[order], twin_key)
    found = (at < len(key)) & (key[order][np.minimum(at, len(key) - 1)] == twin_key)
    if unique_twins:
        after = np.minimum(at + 1, len(key) - 1)
        again = found & (at + 1 < len(key)) & (key[order][after] == twin_key)
        if (again & inside).any():
            return None
    twin = np.where(found, order[np.minimum(at, len(key) - 1)], -1)
    both = inside & (twin >= 0) & inside[np.maximum(twin, 0)]
    if not both.any():
        return 0.0
    summed = np.zeros((mesh.n_faces, 3))
    np.add.at(summed, mesh.face_of_corner, np.cross(p[he[:, 0]], p[he[:, 1]]))
    normal = unit_rows(summed)
    a = normal[mesh.face_of_corner[both]]
    b = normal[mesh.face_of_corner[twin[both]]]
    cosine = np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)
    return float(np.degrees(np.arccos(cosine)).max())


def probe_regions(mesh: PolygonMesh, loops: list[IntArray], known: BoolArray,
                  count: int = PROBES) -> list[BoolArray]:
    """Up to ``count`` probe holes around the hole with the border ``loops``.

    A probe is the faces with a vertex inside a sphere about a vertex near the hole
    (``count`` centres spread by farthest-point sampling among the nearest candidates),
    with the hole's radius (the mean distance of its loop vertices to their centroid,
    times 0.8, as a punched sphere's faces end one ring inside their loop), centred
    beyond the hole's farthest loop vertex by that radius and two edges. Every face
    touching a probe's vertices must be ``known`` ((F,) bool: input faces, not a fill),
    the probe must not touch the hole's loops, and the two rings of faces around it must
    hold at least as many faces as the probe (a small part would leave the fairing no
    surface to continue), and no edge of the probe and its ring may be sharper than the
    sharpest edge between faces touching the hole (and :data:`SHARPNESS_RINGS` rings
    beyond them) by more than
    :data:`SHARPNESS_TOLERANCE` (:func:`sharpest_edge`).

    Returns
    -------
    list of (F,) bool
        The faces of each probe.
    """
    p = mesh.vertices
    ring = np.concatenate(loops)
    centre = p[ring].mean(axis=0)
    spans = np.linalg.norm(p[ring] - centre, axis=1)
    radius = 0.8 * float(spans.mean())
    if radius <= 0:
        return []
    edge = float(np.mean([np.linalg.norm(p[loop] - p[np.roll(loop, -1)], axis=1).mean()
                          for loop in loops]))
    nearest = float(spans.max()) + radius + 2.0 * edge  # a probe's ring clear of the hole's
    near_hole = np.zeros(mesh.n_vertices, dtype=bool)
    near_hole[ring] = True
    for _ in range(SHARPNESS_RINGS):
        near_hole |= vertices_of(mesh, faces_touching(mesh, near_hole))
    sharpest = sharpest_edge(mesh, faces_touching(mesh, near_hole)) + SHARPNESS_TOLERANCE
    of_known = vertices_of(mesh, known)
    clean = of_known & ~vertices_of(mesh, ~known)  # only known faces
    clean[ring] = False
    distance = np.linalg.norm(p - centre, axis=1)
    candidates = np.flatnonzero(clean & (distance > nearest))
    candidates = candidates[np.argsort(distance[candidates])][: 12 * count]
    regions: list[BoolArray] = []
    spread = np.full(len(candidates), np.inf)
    for tried in range(len(candidates)):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        if len(regions) == count:
            break
        pick = int(np.argmax(spread)) if tried else 0
        v = int(candidates[pick])
        spread = np.minimum(spread, np.linalg.norm(p[candidates] - p[v], axis=1))
        spread[pick] = -np.inf
        inside = (np.linalg.norm(p - p[v], axis=1) < radius) & of_known
        inside[v] = True
        faces = faces_touching(mesh, inside)
        touched = vertices_of(mesh, faces)
        if (faces & ~known).any() or touched[ring].any():
            continue
        around = faces_touching(mesh, touched)
        if (around & ~known).any():
            continue  # the probe's ring must be known too
        beyond = faces_touching(mesh, vertices_of(mesh, around)) & ~faces
        if beyond.sum() < max(faces.sum(), 3):
            continue  # a small part, nearly all probe: no surface around it to continue
        if sharpest_edge(mesh, around) > sharpest:
            continue  # across a rim or crease the hole does not have
        probe_loops = patch_loops(mesh, faces)
        if probe_loops is None or len(probe_loops) != 1:
            continue  # not a disc
        regions.append(faces)
    return regions


def _triangles(mesh: PolygonMesh, faces: BoolArray) -> FloatArray:
    """The corners of the triangulated ``faces`` of ``mesh``, (T, 3, 3)."""

    triangles, _ = triangulate_faces(faces_subset(mesh, faces))
    return mesh.vertices[triangles]


def _fair_fill(local: PolygonMesh, loops: list[IntArray], policy: FillPolicy
               ) -> FloatArray | None:
    """The fairing's fill of the probe: a fan per loop, refined and faired (the
    ``policy``'s, :func:`spacemesh.repair.fill.fairing.fair_patch`), as triangle
    corners."""
    filled, _ = fan_fill(local, loops)
    patch = np.arange(filled.n_faces) >= local.n_faces
    free = np.arange(filled.n_vertices) >= local.n_vertices
    faired, source, _ = policy.fair(filled, patch, free, patch_edge_length(filled, patch))
    made = (source < 0) | patch[np.maximum(source, 0)]
    return _triangles(faired, made)


def _meshfix_probe(local: PolygonMesh, loops: list[IntArray], policy: FillPolicy
                   ) -> FloatArray | None:
    """MeshFix's fill of the probe (the ``policy``'s), as triangle corners (None where it
    has none)."""
    filled = policy.meshfix_fill(local, loops)
    if filled is None:
        return None
    points, triangles = filled
    return np.concatenate([local.vertices, points])[triangles]


def _flat_probe(local: PolygonMesh, loops: list[IntArray], policy: FillPolicy
                ) -> FloatArray | None:
    """The least-area flat fill of the probe
    (:func:`spacemesh.repair.fill.flat.flat_surface`), as triangle corners."""
    triangles = flat_surface(local.vertices, loops, policy.max_flat_loop)
    return None if triangles is None else local.vertices[triangles]


#: The fill of a probe by each alternative the probes can weigh against the fairing's
#: (:attr:`spacemesh.repair.fill.policy.FillPolicy.alternatives`): MeshFix's
#: (triangulated, refined, faired) and the least-area flat triangulation of the loop.
ALTERNATIVES = {FillKind.MESHFIX: _meshfix_probe, FillKind.FLAT: _flat_probe}


def probe_errors(mesh: PolygonMesh, loops: list[IntArray], known: BoolArray,
                 count: int = PROBES, policy: FillPolicy = DEFAULT_POLICY
                 ) -> dict[str, tuple[float, float, int]]:
    """For each of the ``policy``'s alternatives (by its name): the fairing's and its
    summed :func:`fill_error` over the probe holes around the hole ``loops`` of ``mesh``
    (its faces ``known`` are input faces) that both could fill, and the number of those
    probes."""
    totals = {kind.value: [0.0, 0.0, 0] for kind in policy.alternatives}
    for faces in probe_regions(mesh, loops, known, count):
        checkpoint()
        around = faces_around(mesh, vertices_of(mesh, faces), PROBE_RINGS)
        probe_loops = patch_loops(mesh, faces)
        assert probe_loops is not None  # a probe is a disc (probe_regions)
        local = faces_subset(mesh, around & ~faces)
        truth = _triangles(mesh, faces)
        ours = _fair_fill(local, probe_loops, policy)
        if ours is None:
            continue
        fair_error = fill_error(truth, ours)
        for kind in policy.alternatives:
            theirs = ALTERNATIVES[kind](local, probe_loops, policy)
            if theirs is None:
                continue
            totals[kind.value][0] += fair_error
            totals[kind.value][1] += fill_error(truth, theirs)
            totals[kind.value][2] += 1
    return {name: (fair, other, int(used)) for name, (fair, other, used) in totals.items()}


def choose_fill(errors: dict[str, tuple[float, float, int]],
                policy: FillPolicy = DEFAULT_POLICY, report: dict | None = None) -> FillKind:
    """The fill the probe errors ``errors`` (:func:`probe_errors`) prefer: the
    alternative whose error over the probes both could fill is below its margin times
    the fairing's (the ``policy``'s ``meshfix_margin`` for MeshFix's fill,
    ``probe_margin`` for the others) by the largest factor, else :attr:`FillKind.FAIR`.
    ``report`` receives the errors (``probe_fair``, ``probe_<name>``, over the probes
    MeshFix could fill, and ``probes``) and ``probe_holes``, the number of probes the
    fairing and at least one alternative filled."""
    if report is not None:
        fair, _, used = errors.get(FillKind.MESHFIX.value, (0.0, 0.0, 0))
        report.update(probe_fair=fair, probes=used,
                      probe_holes=max((count for _, _, count in errors.values()), default=0),
                      **{f"probe_{name}": other for name, (_, other, _) in errors.items()})
    best, best_ratio = FillKind.FAIR, 1.0
    for name, (fair, other, used) in errors.items():
        margin = policy.meshfix_margin if name == FillKind.MESHFIX else policy.probe_margin
        if used and other < best_ratio * margin * fair:
            best, best_ratio = FillKind(name), other / (margin * fair)
    return best


def preferred_fill(mesh: PolygonMesh, loops: list[IntArray], known: BoolArray,
                   report: dict | None = None, policy: FillPolicy = DEFAULT_POLICY
                   ) -> FillKind:
    """The fill the probe holes around the hole ``loops`` prefer: :func:`choose_fill` of
    their :func:`probe_errors` under the ``policy`` (``report`` as there)."""
    return choose_fill(probe_errors(mesh, loops, known, policy=policy), policy, report)
