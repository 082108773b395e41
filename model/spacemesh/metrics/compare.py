"""All metrics of one predicted mesh against one ground truth, as one flat row.

A :class:`Reference` holds what every prediction of a shape is compared with (the
ground truth's samples, edge points, KD-tree and element-shape distributions), so it
is computed once per shape and shared by our model and every baseline.

Row keys (see :data:`METRIC_KEYS`): ``cd``, ``f1``, ``ecd``, ``ef1``, ``in`` (a fraction),
``n_vertices``, ``n_faces``, ``manifold``, ``watertight``, ``oriented``, ``valid``,
``components``, ``pieces`` and ``genus`` (:func:`spacemesh.topology.surface_topology`),
``topology`` (pieces and genus both equal the ground truth's), ``self_intersections``
(fraction of faces), ``edge_length_w1``,
``corner_angle_w1``, ``mean_edge_length``, ``mean_corner_angle`` and ``degrees`` (the
face-degree histogram as ``"3:120 4:8"``). A prediction with no surface gets NaN for
every geometric metric.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.distance import F1_THRESHOLD, chamfer_f1
from spacemesh.metrics.edges import EF1_THRESHOLD, edge_chamfer_f1, edge_points
from spacemesh.metrics.normals import IN_DEGREES, inaccurate_normals
from spacemesh.metrics.quality import (
    corner_angles,
    distribution_distance,
    edge_lengths,
    self_intersection_fraction,
    topology_flags,
)
from spacemesh.metrics.sampling import N_SAMPLES, SurfaceSamples, sample_mesh
from spacemesh.topology import SurfaceTopology, surface_topology
from spacemesh.typed import FloatArray

#: Every key of a row from :func:`score_mesh`, in table order.
METRIC_KEYS = (
    "cd",
    "f1",
    "ecd",
    "ef1",
    "in",
    "n_vertices",
    "n_faces",
    "manifold",
    "watertight",
    "oriented",
    "valid",
    "components",
    "pieces",
    "genus",
    "topology",
    "self_intersections",
    "edge_length_w1",
    "corner_angle_w1",
    "mean_edge_length",
    "mean_corner_angle",
    "degrees",
)


@dataclass(frozen=True)
class MetricOptions:
    """Parameters of the metrics (defaults: Supplement C).

    Attributes
    ----------
    samples : int
        Points sampled on each mesh.
    f1_threshold, ef1_threshold : float
        F-score thresholds in the [-1, 1] frame.
    in_degrees : float
        IN angle threshold.
"""

    samples: int = N_SAMPLES
    f1_threshold: float = F1_THRESHOLD
    ef1_threshold: float = EF1_THRESHOLD
    in_degrees: float = IN_DEGREES


@dataclass(frozen=True)
class Reference:
    """A ground-truth mesh prepared for comparisons (in its own [-1, 1] frame).

    Attributes
    ----------
    mesh : PolygonMesh
    samples : SurfaceSamples
    edges : SurfaceSamples
        The edge points among ``samples``.
    tree : cKDTree
        Of ``samples.points``.
    edge_lengths : (E,) float64
    corner_angles : (S,) float64
    options : MetricOptions
    topology : SurfaceTopology
        The ground truth's pieces, genus and boundary loops.
    """

    mesh: PolygonMesh
    samples: SurfaceSamples
    edges: SurfaceSamples
    tree: cKDTree
    edge_lengths: FloatArray
    corner_angles: FloatArray
    options: MetricOptions
    topology: SurfaceTopology

    @classmethod
    def from_mesh(
        cls, mesh: PolygonMesh, *, seed: int | list[int] = 0, options: MetricOptions | None = None
    ) -> Reference:
        """Sample and prepare a ground truth that is already normalised.

        Parameters
        ----------
        mesh : PolygonMesh
            Ground truth in its [-1, 1] frame (see :mod:`spacemesh.metrics.sampling`).
        seed : int or list of int
            Sampling seed.
        options : MetricOptions, optional

        Returns
        -------
        Reference
        """
        options = options or MetricOptions()
        samples = sample_mesh(mesh, options.samples, seed)
        if len(samples) == 0:
            raise ValueError("the ground truth has no surface to sample")
        return cls(
            mesh,
            samples,
            edge_points(samples),
            cKDTree(samples.points),
            edge_lengths(mesh),
            corner_angles(mesh),
            options,
            surface_topology(mesh),
        )


def format_degrees(histogram: dict[int, int]) -> str:
    """A degree histogram as ``"3:120 4:8"``."""
    return " ".join(f"{k}:{v}" for k, v in sorted(histogram.items()))


def score_mesh(
    mesh: PolygonMesh, reference: Reference, *, seed: int | list[int] = 1,
    open_surface: bool = False,
) -> dict[str, Any]:
    """Every metric of a prediction against a reference (keys in :data:`METRIC_KEYS`).

    Parameters
    ----------
    mesh : PolygonMesh
        The prediction, in the reference's frame.
    reference : Reference
    seed : int or list of int
        Seed of the prediction's samples.
    open_surface : bool
        The prediction was declared open (its fit report): ``valid`` allows boundary
        edges (:func:`topology_flags`).

    Returns
    -------
    dict
        ``in`` and ``self_intersections`` are fractions in [0, 1].
    """
    options = reference.options
    row: dict[str, Any] = {"n_vertices": int(mesh.n_vertices), "n_faces": int(mesh.n_faces)}
    row.update(topology_flags(mesh, open_surface))
    shape = surface_topology(mesh)
    row.update(pieces=shape.pieces, genus=shape.genus,
               topology=(shape.pieces, shape.genus) == (reference.topology.pieces,
                                                         reference.topology.genus))
    samples = sample_mesh(mesh, options.samples, seed)
    if len(samples):
        scores = chamfer_f1(
            samples.points, reference.samples.points, options.f1_threshold, gt_tree=reference.tree
        )
        edges = edge_chamfer_f1(edge_points(samples), reference.edges, options.ef1_threshold)
        row.update(
            cd=scores.chamfer,
            f1=scores.f1,
            ecd=edges.chamfer,
            ef1=edges.f1,
            **{
                "in": inaccurate_normals(
                    samples, reference.samples, options.in_degrees, gt_tree=reference.tree
                )
            },
        )
    else:
        row.update(cd=np.nan, f1=np.nan, ecd=np.nan, ef1=np.nan, **{"in": np.nan})
    lengths, angles = edge_lengths(mesh), corner_angles(mesh)
    row.update(
        self_intersections=self_intersection_fraction(mesh),
        edge_length_w1=distribution_distance(lengths, reference.edge_lengths),
        corner_angle_w1=distribution_distance(angles, reference.corner_angles),
        mean_edge_length=float(lengths.mean()) if len(lengths) else np.nan,
        mean_corner_angle=float(angles.mean()) if len(angles) else np.nan,
        degrees=format_degrees(mesh.degree_histogram()),
    )
    return {key: row[key] for key in METRIC_KEYS}
