"""Surface samples for the metrics: seeded, area-weighted, with face normals, in one frame.

Every metric compares meshes in the frame of the ground truth normalised so that its
longest bounding-box axis spans [-1, 1] (Supplement C of the paper); the prediction is
moved by the *same* transform, so an error of scale or position is still measured.
Points are drawn by :func:`spacemesh.primitives.sample_surface` (uniform by area on
the triangulation, each point carrying the normal of the polygon face it lies on), the
same sampler that makes the conditioning point clouds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import normalize, sample_surface, surface_area
from spacemesh.typed import FloatArray

#: Points sampled on each mesh (Supplement C: 10,000).
N_SAMPLES = 10_000


@dataclass(frozen=True)
class SurfaceSamples:
    """Points on a surface with their unit normals.

    Attributes
    ----------
    points : (N, 3) float64
    normals : (N, 3) float64
    """

    points: FloatArray
    normals: FloatArray

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, mask: np.ndarray) -> SurfaceSamples:
        """The samples selected by a boolean mask or index array."""
        return SurfaceSamples(self.points[mask], self.normals[mask])


def normalisation(mesh: PolygonMesh) -> tuple[FloatArray, float]:
    """The transform that puts ``mesh``'s bounding box in [-1, 1] (longest axis).

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    centre : (3,) float64
    scale : float
        Normalised positions are ``(x - centre) / scale``.
    """
    _, centre, scale = normalize(mesh)
    return centre, scale


def apply_normalisation(mesh: PolygonMesh, centre: FloatArray, scale: float) -> PolygonMesh:
    """``mesh`` moved by the transform of :func:`normalisation` (of another mesh)."""
    return mesh.with_vertices((mesh.vertices - centre) / scale)


def sample_mesh(
    mesh: PolygonMesh, count: int = N_SAMPLES, seed: int | list[int] = 0
) -> SurfaceSamples:
    """Sample ``count`` points uniformly by area, with the normals of their faces.

    Parameters
    ----------
    mesh : PolygonMesh
        Any polygon mesh (faces are triangulated for the area weights).
    count : int
    seed : int or list of int
        Seed of :func:`numpy.random.default_rng`; the same seed gives the same samples.

    Returns
    -------
    SurfaceSamples
        Empty (0 points) when the mesh has no face of positive area.
    """
    empty = SurfaceSamples(np.zeros((0, 3)), np.zeros((0, 3)))
    if mesh.n_faces == 0 or not surface_area(mesh) > 0:
        return empty
    points, normals = sample_surface(mesh, count, np.random.default_rng(seed))  # (N, 3) each
    return SurfaceSamples(points.astype(np.float64), normals.astype(np.float64))

