"""The local patch the model sees: the region plus rings of kept faces, renormalised.

The diffusion model has a fixed number of vertex tokens ``N`` (``max_vertices`` of the
model). The *known* vertices it must hold are the hole's boundary vertices and the
vertices of the kept faces within ``rings`` face rings of the region; the other tokens
are free to become new vertices. ``rings`` is the largest number (at most
:data:`MAX_RINGS`) that leaves the free tokens the hole needs; for a small mesh the
rings reach every face and the patch is the whole mesh, as in the paper.

The patch is normalised like a generation request (bounding-box centre to the origin,
longest axis to [-1, 1], :func:`spacemesh.runtime.request.normalize_points`) over its
faces' vertices and the hole. Everything the inpainting needs is sampled here, in that
unit frame:

- the conditioning points, on the patch's original faces (the region's too: the
  region is badly tessellated, not badly shaped);
- the hole points that pad the known vertices for the alignment, on the removed faces,
  plus a centroid fan over each loop that is open in the input (a hole without faces);
- an equal density of points on the kept faces of the patch, used to decide which
  generated vertices belong to the hole.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import edge_keys, sample_surface, surface_area
from spacemesh.repair.cut import Cut
from spacemesh.repair.region import INVALID_REGION, REGION_TOO_LARGE, RegionError
from spacemesh.runtime.request import normalize_points
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Most face rings of context around the region.
MAX_RINGS = 16
#: Fewest free tokens left for new vertices.
MIN_FREE = 8
#: Free tokens per vertex the hole is expected to need.
FREE_PER_EXPECTED = 2.0


@dataclass(frozen=True)
class Patch:
    """The part of a cut mesh the model works on.

    Attributes
    ----------
    faces : (F_p,) int64
        Input faces in the patch: the region and the kept faces of the rings.
    known : (K,) int64
        Input vertices held by the diffusion (ascending; contains ``cut.boundary``).
    rings : int
        Rings of kept faces around the region.
    n_tokens : int
        The model's vertex tokens ``N``.
    expected_new : int
        Estimate of the vertices the hole needs (sets the free-token budget).
    centre : (3,) float64
    scale : float
        ``unit = (x - centre) / scale``.
    """

    faces: IntArray
    known: IntArray
    rings: int
    n_tokens: int
    expected_new: int
    centre: FloatArray
    scale: float

    @property
    def n_free(self) -> int:
        """Tokens not held by known vertices."""
        return self.n_tokens - len(self.known)

    def to_unit(self, points: FloatArray) -> FloatArray:
        """Mesh frame to the patch's unit frame."""
        return (np.asarray(points, np.float64) - self.centre) / self.scale

    def from_unit(self, points: FloatArray) -> FloatArray:
        """The patch's unit frame to the mesh frame."""
        return np.asarray(points, np.float64) * self.scale + self.centre


def sub_mesh(mesh: PolygonMesh, faces: IntArray) -> PolygonMesh:
    """The faces ``faces`` of ``mesh`` over all of its vertices."""
    sizes = mesh.face_sizes[faces]
    starts = np.repeat(mesh.face_offsets[faces], sizes)
    local = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    return PolygonMesh(mesh.vertices, mesh.face_indices[starts + local], offsets)


def open_loops(cut: Cut) -> list[IntArray]:
    """The loops with at least one edge that no removed face has (holes in the input)."""
    mesh = cut.mesh
    region_mesh = sub_mesh(mesh, np.flatnonzero(cut.region))
    keys = np.unique(edge_keys(region_mesh.halfedges, mesh.n_vertices))
    out = []
    for loop in cut.loops:
        k = edge_keys(np.stack([loop, np.roll(loop, -1)], axis=1), mesh.n_vertices)
        if not np.isin(k, keys).all():
            out.append(loop)
    return out


def hole_surface(cut: Cut) -> PolygonMesh:
    """The removed faces plus a centroid fan over each loop open in the input.

    Returns
    -------
    PolygonMesh
        Over the input's vertices followed by one centroid per open loop.
    """
    mesh = cut.mesh
    removed = sub_mesh(mesh, np.flatnonzero(cut.region))
    loops = open_loops(cut)
    centroids = np.array([mesh.vertices[loop].mean(axis=0) for loop in loops]).reshape(-1, 3)
    fans = []
    for c, loop in enumerate(loops):
        centre = mesh.n_vertices + c
        fans.extend([[int(a), int(b), centre] for a, b in zip(loop, np.roll(loop, -1),
                                                              strict=True)])
    faces = removed.faces + [np.asarray(f, dtype=np.int64) for f in fans]
    return PolygonMesh.from_faces(np.concatenate([mesh.vertices, centroids]), faces)


def _area(mesh: PolygonMesh) -> float:
    return surface_area(mesh) if mesh.n_faces else 0.0


def expected_new_vertices(cut: Cut, hole: PolygonMesh) -> int:
    """Vertices the hole is expected to need at the surrounding density.

    The larger of the removed vertex count and ``hole area x vertex density``, the
    density measured on the kept faces around the hole (their corners divided by the
    mesh's mean valence, per unit area).
    """
    mesh = cut.mesh
    on_boundary = np.zeros(mesh.n_vertices, dtype=bool)
    on_boundary[cut.boundary] = True
    near = np.zeros(mesh.n_faces, dtype=bool)
    near[mesh.face_of_corner[on_boundary[mesh.face_indices]]] = True
    ring = sub_mesh(mesh, np.flatnonzero(near & ~cut.region))
    valence = mesh.face_indices.size / max(mesh.n_vertices, 1)
    ring_area = _area(ring)
    density = ring.face_indices.size / valence / ring_area if ring_area > 0 else 0.0
    return int(max(len(cut.removed_vertices), math.ceil(_area(hole) * density)))


def plan_patch(cut: Cut, n_tokens: int, *, max_rings: int = MAX_RINGS,
               hole: PolygonMesh | None = None) -> Patch:
    """Choose the rings of context that fit the model's vertex tokens.

    Parameters
    ----------
    cut : Cut
    n_tokens : int
        The model's ``max_vertices``.
    max_rings : int
        Upper bound on the rings.
    hole : PolygonMesh, optional
        :func:`hole_surface` of ``cut`` (computed when None).

    Returns
    -------
    Patch

    Raises
    ------
    RegionError
        ``region-too-large`` when the boundary alone leaves fewer than
        :data:`MIN_FREE` free tokens; ``invalid-region`` when there is nothing to
        sample (:func:`check_samplable`).
    """
    mesh = cut.mesh
    hole = hole_surface(cut) if hole is None else hole
    expected = expected_new_vertices(cut, hole)
    n_boundary = len(cut.boundary)
    if n_boundary + MIN_FREE > n_tokens:
        raise RegionError(
            REGION_TOO_LARGE,
            f"the region's boundary has {n_boundary} vertices; the model holds at most "
            f"{n_tokens - MIN_FREE} (it has {n_tokens} vertex tokens and keeps {MIN_FREE} "
            "for new vertices): mark a smaller region or repair it in parts",
            {"boundary_vertices": n_boundary, "max_boundary_vertices": n_tokens - MIN_FREE},
        )
    need_free = max(MIN_FREE, math.ceil(FREE_PER_EXPECTED * expected))
    budget = max(n_tokens - need_free, n_boundary)
    region_faces = np.flatnonzero(cut.region)
    kept = ~cut.region
    known = np.asarray(cut.boundary, dtype=np.int64)
    ring_faces = np.zeros(0, dtype=np.int64)
    frontier = np.zeros(mesh.n_vertices, dtype=bool)
    frontier[cut.boundary] = True
    in_patch = np.zeros(mesh.n_faces, dtype=bool)
    rings = 0
    for r in range(1, max_rings + 1):
        touching = np.zeros(mesh.n_faces, dtype=bool)
        touching[mesh.face_of_corner[frontier[mesh.face_indices]]] = True
        grown = in_patch | (touching & kept)
        if grown.sum() == in_patch.sum():
            break  # the rings reached every kept face connected to the hole
        candidate_faces = np.flatnonzero(grown)
        candidate_known = np.union1d(cut.boundary,
                                     sub_mesh(mesh, candidate_faces).face_indices)
        if len(candidate_known) > budget:
            break
        in_patch, ring_faces, known, rings = grown, candidate_faces, candidate_known, r
        frontier = np.zeros(mesh.n_vertices, dtype=bool)
        frontier[known] = True
    faces = np.union1d(region_faces, ring_faces)
    check_samplable(cut, faces, hole)
    extent = np.concatenate([mesh.vertices[sub_mesh(mesh, faces).face_indices],
                             hole.vertices[hole.face_indices]])
    _, centre, scale = normalize_points(extent)
    return Patch(faces, known, rings, int(n_tokens), expected, centre, scale)


def check_samplable(cut: Cut, faces: IntArray, hole: PolygonMesh) -> None:
    """Refuse a patch that :func:`sample_patch` has nothing to sample on.

    The conditioning points are sampled on the patch's faces and the hole points on the
    hole (or, for a hole without area, at its boundary vertices): a patch of faces with
    fewer than three vertices, or a hole with neither area nor boundary (a region of
    such faces cut off from the rest of the mesh), leaves nothing.

    Parameters
    ----------
    cut : Cut
    faces : (K,) int64
        The patch's faces.
    hole : PolygonMesh
        :func:`hole_surface` of ``cut``.

    Raises
    ------
    RegionError
        ``invalid-region``, naming a region face with fewer than three vertices when
        there is one.
    """
    mesh = cut.mesh
    if (mesh.face_sizes[faces] >= 3).any() and (len(cut.boundary) or _area(hole) > 0):
        return
    small = np.flatnonzero(cut.region & (mesh.face_sizes < 3))
    why = (f"face {int(small[0])} has {int(mesh.face_sizes[small[0]])} vertices"
           if small.size else "its faces have no area")
    raise RegionError(INVALID_REGION, f"the region has no surface to re-generate ({why}) "
                      "and no boundary with the rest of the mesh; mark the faces around it "
                      "as well")


@dataclass(frozen=True)
class PatchSamples:
    """Point sets of a patch in its unit frame.

    Attributes
    ----------
    condition : (P, 3 or 6) float32
        Encoder input (points, then normals when the model reads them).
    hole : (H, 3) float64
        Points in the hole (pads the known vertices for the alignment).
    kept : (Q, 3) float64
        Points on the patch's kept faces, at the hole points' density.
    """

    condition: np.ndarray
    hole: FloatArray
    kept: FloatArray


def sample_patch(cut: Cut, patch: Patch, *, n_points: int, normals: bool, n_hole: int,
                 rng: np.random.Generator, hole: PolygonMesh | None = None) -> PatchSamples:
    """Sample the conditioning, hole and kept point sets of a patch.

    Parameters
    ----------
    cut : Cut
    patch : Patch
    n_points : int
        Encoder points.
    normals : bool
        Append unit normals to the conditioning points.
    n_hole : int
        Hole points (at least the patch's free tokens).
    rng : numpy.random.Generator
    hole : PolygonMesh, optional
        :func:`hole_surface` of ``cut``.

    Returns
    -------
    PatchSamples
    """
    mesh = cut.mesh
    hole = hole_surface(cut) if hole is None else hole
    surface = sub_mesh(mesh, patch.faces)
    points, point_normals = sample_surface(surface, n_points, rng)  # (P, 3) each
    columns = [patch.to_unit(points)]
    if normals:
        columns.append(point_normals.astype(np.float64))
    condition = np.concatenate(columns, axis=1).astype(np.float32)
    hole_area = _area(hole)
    if hole_area > 0:
        hole_points = patch.to_unit(sample_surface(hole, n_hole, rng)[0])
    else:
        hole_points = patch.to_unit(mesh.vertices[cut.boundary])[
            rng.integers(0, len(cut.boundary), n_hole)]
    kept_faces = np.setdiff1d(patch.faces, np.flatnonzero(cut.region))
    kept_mesh = sub_mesh(mesh, kept_faces)
    kept_area = _area(kept_mesh)
    n_kept = int(min(20 * n_hole, math.ceil(n_hole * kept_area / max(hole_area, 1e-30))))
    kept_points = (patch.to_unit(sample_surface(kept_mesh, max(n_kept, 1), rng)[0])
                   if kept_area > 0 else patch.to_unit(mesh.vertices[patch.known]))
    return PatchSamples(condition, hole_points.astype(np.float64),
                        kept_points.astype(np.float64))


def in_hole(points: FloatArray, samples: PatchSamples) -> BoolArray:
    """(M,) points whose nearest sample is a hole point rather than a kept-face point."""
    from scipy.spatial import cKDTree

    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    d_hole, _ = cKDTree(samples.hole).query(points)
    d_kept, _ = cKDTree(samples.kept).query(points)
    return d_hole < d_kept
