"""The paper's evaluation metrics (Supplement C, following NDC) and mesh-quality statistics.

All distances are measured in the ground truth's frame normalised so that its longest
axis spans [-1, 1], on 10,000 seeded surface samples per mesh.

- :mod:`~spacemesh.metrics.sampling`: the frame and the surface samples.
- :mod:`~spacemesh.metrics.distance`: Chamfer distance (CD) and F-score (F1 at 0.02).
- :mod:`~spacemesh.metrics.edges`: edge points, edge Chamfer distance (ECD) and EF1.
- :mod:`~spacemesh.metrics.normals`: IN, the fraction of normals more than 10 degrees off.
- :mod:`~spacemesh.metrics.quality`: validity rates, self-intersections, edge-length and
  corner-angle distributions and their distance to the ground truth's, face degrees.
- :mod:`~spacemesh.metrics.compare`: every metric of one prediction as one row.
- :mod:`~spacemesh.metrics.report`: rows into the Table-1 markdown, CSV and histograms.
"""

from spacemesh.metrics.compare import METRIC_KEYS, MetricOptions, Reference, score_mesh
from spacemesh.metrics.distance import F1_THRESHOLD, DistanceScores, chamfer_f1
from spacemesh.metrics.edges import edge_chamfer_f1, edge_mask, edge_points
from spacemesh.metrics.normals import IN_DEGREES, inaccurate_normals
from spacemesh.metrics.quality import (
    corner_angles,
    distribution_distance,
    edge_lengths,
    self_intersection_fraction,
    topology_flags,
)
from spacemesh.metrics.sampling import (
    N_SAMPLES,
    SurfaceSamples,
    apply_normalisation,
    normalisation,
    sample_mesh,
)

__all__ = [
    "F1_THRESHOLD",
    "IN_DEGREES",
    "METRIC_KEYS",
    "N_SAMPLES",
    "DistanceScores",
    "MetricOptions",
    "Reference",
    "SurfaceSamples",
    "apply_normalisation",
    "chamfer_f1",
    "corner_angles",
    "distribution_distance",
    "edge_chamfer_f1",
    "edge_lengths",
    "edge_mask",
    "edge_points",
    "inaccurate_normals",
    "normalisation",
    "sample_mesh",
    "score_mesh",
    "self_intersection_fraction",
    "topology_flags",
]
