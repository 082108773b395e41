"""From dataset records to padded training batches.

A :class:`Batch` holds, for ``B`` meshes padded to ``N`` vertices (real vertices first):
conditioning points, positions, the validity mask, the dense ground-truth adjacency
``(B, N, N)`` and the meshes' connectivities concatenated into one graph over the
flattened ``B * N`` vertices (vertex ``i`` of mesh ``b`` is ``b * N + i``), as the padded
neighbour table the permutation loss takes (:class:`spacemesh.nn.model.NeighbourTable`).

Augmentation: each shape is scaled by an independent random factor per axis and then
renormalised (bounding-box centre at the origin, longest axis spanning [-1, 1]), the
normalisation the generator applies to its inputs. Normals follow the inverse transpose.
An :class:`spacemesh.data.augment.AugmentConfig` then makes the conditioning cloud
realistic (noise, uneven density, missing regions, outliers); the positions, adjacency
and neighbour table stay those of the clean mesh.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from spacemesh.connectivity import Connectivity
from spacemesh.data.augment import AugmentConfig, augment_cloud
from spacemesh.data.shards import MeshRecord
from spacemesh.encode import encode_connectivity
from spacemesh.nn.model import NeighbourTable
from spacemesh.runtime.request import choose_points
from spacemesh.typed import FloatArray


@dataclass(frozen=True)
class Sample:
    """One training shape, prepared once.

    Attributes
    ----------
    shape_id : str
    positions : (V, 3) float32
    points, normals : (P, 3) float32
    connectivity : Connectivity
        Ground truth from :func:`spacemesh.encode.encode_connectivity`.
    """

    shape_id: str
    positions: FloatArray
    points: FloatArray
    normals: FloatArray
    connectivity: Connectivity

    @property
    def n_vertices(self) -> int:
        """``V``."""
        return len(self.positions)


def prepare_sample(record: MeshRecord) -> Sample:
    """Encode a record's ground-truth connectivity.

    Parameters
    ----------
    record : MeshRecord

    Returns
    -------
    Sample
    """
    return Sample(
        shape_id=record.shape_id,
        positions=np.asarray(record.mesh.vertices, np.float32),
        points=np.asarray(record.points, np.float32),
        normals=np.asarray(record.normals, np.float32),
        connectivity=encode_connectivity(record.mesh, check=False),
    )


@dataclass
class Batch:
    """Padded tensors of ``B`` meshes (see the module docstring).

    Attributes
    ----------
    points : (B, P, 3 or 6) float32
    positions : (B, N, 3) float32
    valid : (B, N) bool
    adjacency : (B, N, N) bool, or None
    table : NeighbourTable, or None
    samples : list of Sample
    """

    points: torch.Tensor
    positions: torch.Tensor
    valid: torch.Tensor
    adjacency: torch.Tensor | None
    table: NeighbourTable | None
    samples: list[Sample]

    def to(self, device: torch.device | str) -> Batch:
        """The batch on ``device``."""
        return Batch(
            self.points.to(device), self.positions.to(device), self.valid.to(device),
            None if self.adjacency is None else self.adjacency.to(device),
            None if self.table is None else self.table.to(device),
            self.samples,
        )


def random_scaling(
    positions: FloatArray, points: FloatArray, normals: FloatArray, scale: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Scale per axis, then renormalise by the vertices' bounding box.

    Parameters
    ----------
    positions : (V, 3)
    points, normals : (P, 3)
    scale : (3,) positive factors

    Returns
    -------
    positions, points, normals
        Transformed (normals renormalised to unit length).
    """
    v = positions * scale
    lo, hi = v.min(0), v.max(0)
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-12)
    n = normals / scale
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return (
        ((v - centre) / half).astype(np.float32),
        ((points * scale - centre) / half).astype(np.float32),
        n.astype(np.float32),
    )


def concat_connectivity(connectivities: Sequence[Connectivity], n: int) -> Connectivity:
    """One connectivity over ``len(connectivities) * n`` vertices (mesh ``b`` at ``b * n``).

    Parameters
    ----------
    connectivities : sequence of Connectivity
        Each with at most ``n`` vertices.
    n : int
        Padded vertex count.

    Returns
    -------
    Connectivity
    """
    offsets, neighbours, successor = [np.zeros(1, np.int64)], [], []
    slot_base = 0
    for b, conn in enumerate(connectivities):
        degree = np.zeros(n, np.int64)
        degree[: conn.n_vertices] = conn.degree
        offsets.append(slot_base + np.cumsum(degree))
        neighbours.append(conn.neighbours + b * n)
        successor.append(conn.successor + slot_base)
        slot_base += len(conn.neighbours)
    return Connectivity(
        len(connectivities) * n, np.concatenate(offsets),
        np.concatenate(neighbours), np.concatenate(successor),
    )


def collate(
    samples: Sequence[Sample],
    *,
    n_points: int,
    normals: bool,
    pad_to: int | None = None,
    connectivity: bool = True,
    rng: np.random.Generator | None = None,
    scale_range: tuple[float, float] | None = None,
    jitter: float = 0.0,
    augment: AugmentConfig | None = None,
) -> Batch:
    """Pad samples into a :class:`Batch`.

    Parameters
    ----------
    samples : sequence of Sample
    n_points : int
        Conditioning points per shape.
    normals : bool
        Append normals to the points (6 channels).
    pad_to : int, optional
        Vertex count ``N`` (default: the largest in the batch).
    connectivity : bool
        Build the adjacency and the neighbour table.
    rng : numpy.random.Generator, optional
        For point subsets and augmentation (deterministic subsets when None).
    scale_range : (float, float), optional
        Per-axis random scaling (no augmentation when None).
    jitter : float
        Standard deviation of Gaussian noise added to the vertex positions after
        scaling (the adjacency and the neighbour table are those of the exact mesh).
    augment : AugmentConfig, optional
        Conditioning-cloud augmentation after the scaling (none when None or identity:
        the points are then a plain random subset, as before).

    Returns
    -------
    Batch
    """
    rng = rng if rng is not None else np.random.default_rng(0)
    n = pad_to if pad_to is not None else max(s.n_vertices for s in samples)
    b = len(samples)
    channels = 6 if normals else 3
    points = np.zeros((b, n_points, channels), np.float32)
    positions = np.zeros((b, n, 3), np.float32)
    valid = np.zeros((b, n), bool)
    adjacency = np.zeros((b, n, n), bool) if connectivity else None
    for i, s in enumerate(samples):
        if s.n_vertices > n:
            raise ValueError(f"shape {s.shape_id} has {s.n_vertices} > {n} vertices")
        v, p, nrm = s.positions, s.points, s.normals
        if scale_range is not None:
            scale = rng.uniform(scale_range[0], scale_range[1], size=3)
            v, p, nrm = random_scaling(v, p, nrm, scale)
        if augment is not None and not augment.is_identity:
            p, nrm, _ = augment_cloud(p, nrm, augment, rng, n_points)
        else:
            pick = choose_points(len(p), n_points, rng)
            p, nrm = p[pick], nrm[pick]
        points[i, :, :3] = p
        if normals:
            points[i, :, 3:] = nrm
        if jitter > 0:
            v = v + rng.normal(scale=jitter, size=v.shape)  # (n_i, 3)
        positions[i, : s.n_vertices] = v
        valid[i, : s.n_vertices] = True
        if adjacency is not None:
            e = s.connectivity.edges
            adjacency[i, e[:, 0], e[:, 1]] = True
            adjacency[i, e[:, 1], e[:, 0]] = True
    table = (
        NeighbourTable.from_connectivity(concat_connectivity([s.connectivity for s in samples], n))
        if connectivity else None
    )
    return Batch(
        torch.from_numpy(points), torch.from_numpy(positions), torch.from_numpy(valid),
        None if adjacency is None else torch.from_numpy(adjacency), table, list(samples),
    )
