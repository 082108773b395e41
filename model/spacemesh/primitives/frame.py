"""The unit frame: a mesh centred on its bounding box, its longest axis spanning [-1, 1]."""

from __future__ import annotations

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray


def normalize(mesh: PolygonMesh) -> tuple[PolygonMesh, FloatArray, float]:
    """Centre the bounding box at the origin and scale the longest axis to [-1, 1].

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    mesh : PolygonMesh
        The normalised mesh.
    centre : (3,) float64
        The original bounding-box centre.
    scale : float
        Original half-extent of the longest axis: ``original = mesh * scale + centre``.
    """
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    centre = (lo + hi) / 2
    scale = float((hi - lo).max()) / 2
    if scale <= 0:
        scale = 1.0
    return mesh.with_vertices((mesh.vertices - centre) / scale), centre, scale
