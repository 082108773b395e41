"""Post-decode geometry: everything that happens to the mesh after the networks.

* :mod:`~spacemesh.geometry.policy`: which model gets which decode steps (manifest ``decode``);
* :mod:`~spacemesh.geometry.sampling`: vertices chosen on the input (farthest points);
* :mod:`~spacemesh.geometry.fitting`: the vertex fit (one energy, one sparse solve);
* :mod:`~spacemesh.geometry.stage`: the stage itself (splits, fit, flips, guard);
* :mod:`~spacemesh.geometry.intersections`: self-intersecting faces (numpy + scipy);
* :mod:`~spacemesh.geometry.surface`: open surfaces, a closed mesh trimmed to its points;
* :mod:`~spacemesh.geometry.sheet`: flat sheets of points, and the slab they are decoded as;
* :mod:`~spacemesh.geometry.report`: the fit report of every response.

numpy and scipy only: the service uses all of it without torch, trimesh or pymeshlab.
"""

from spacemesh.geometry.fitting import VertexFitOptions, fit_vertices
from spacemesh.geometry.report import FitReport, PointFacts, SurfaceFacts, fit_report, fit_score
from spacemesh.geometry.sampling import farthest_point_sampling, feature_weights
from spacemesh.geometry.stage import GeometryOptions, GeometryResult, refine_geometry

__all__ = [
    "FitReport",
    "GeometryOptions",
    "GeometryResult",
    "PointFacts",
    "SurfaceFacts",
    "VertexFitOptions",
    "farthest_point_sampling",
    "feature_weights",
    "fit_report",
    "fit_score",
    "fit_vertices",
    "refine_geometry",
]
