"""What the pipeline needs to know about a model besides its networks: :class:`ModelSpec`,
read from a model repository's manifest (or a training configuration)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from spacemesh.decode import DecodeOptions
from spacemesh.geometry import GeometryOptions
from spacemesh.geometry.policy import decode_changes
from spacemesh.runtime.large import DEFAULT_LARGE_MESHES, check_large_meshes
from spacemesh.runtime.schedule import NoiseSchedule
from spacemesh.typed import FloatArray

#: Sampled vertices closer than this (normalised units) are one vertex: coincident
#: vertices (e.g. two tokens clipped to the same corner of the cube) would give the
#: connectivity network identical inputs, hence exact ties in the decode.
DUPLICATE_TOLERANCE = 1e-4

#: Vertices ``start=points`` chooses when the request sets no ``target_vertices`` and the
#: manifest no ``sampler.vertices``.
DEFAULT_VERTICES = 200

#: Most seeds a model's ``sampler.retry_seeds`` may add to a request's own when none of
#: its meshes has as many pieces as the points and uncrossed faces (larger values are
#: refused on load).
MAX_RETRY_SEEDS = 8


def check_retry_seeds(value: Any) -> int:
    """A manifest's ``sampler.retry_seeds``, checked (0 to :data:`MAX_RETRY_SEEDS`)."""
    if isinstance(value, bool) or not isinstance(value, int) or not (
            0 <= value <= MAX_RETRY_SEEDS):
        raise ValueError(f"sampler.retry_seeds must be an integer from 0 to "
                         f"{MAX_RETRY_SEEDS}, not {value!r}")
    return value


@dataclass(frozen=True)
class ModelSpec:
    """What the pipeline needs to know about a model besides its networks.

    Attributes
    ----------
    n_points : int
        Encoder points.
    max_vertices : int
        Vertex tokens of the diffusion.
    normals : bool
        Whether the encoder reads normals (then every request must bring them).
    schedule : NoiseSchedule
        The trained schedule.
    method : str
        Default sampler (``ddim`` or ``ddpm``).
    steps : int
        Default sampler steps.
    decode : DecodeOptions
        How embeddings are read.
    vertex_spacing : float
        Sampled vertices closer than this (in the normalised [-1, 1] frame) to an
        earlier one are dropped before the connectivity network runs. Diffusion places
        vertices in clumps (median nearest-neighbour distance half the ground truth's on
        the ``small`` model), and a clump of near-duplicates cannot be joined into
        manifold faces, so the decode would have to drop them and their neighbours.
        Calibrated on the training set's val split at export
        (:func:`spacemesh.export.repository.calibrate_vertex_spacing`);
        ``manifest["sampler"]["vertex_spacing"]``, default :data:`DUPLICATE_TOLERANCE`.
    start : {"noise", "points"}
        Default vertex start (``manifest["sampler"]["start"]``; ``noise`` for models
        whose manifest predates it).
    start_time : float
        Default start time of ``start=points`` (``manifest["sampler"]["start_time"]``).
    vertices : int
        Vertices ``start=points`` chooses without ``target_vertices``
        (``manifest["sampler"]["vertices"]``).
    feature_boost : float
        Farthest-point sampling treats points on sharp features as this much farther
        away (1 + boost; :func:`spacemesh.geometry.sampling.feature_weights`), so
        creases and corners get denser vertices (``manifest["sampler"]["feature_boost"]``).
    geometry : GeometryOptions
        The geometry stage (``manifest["geometry"]`` overrides the defaults).
    local_points : int
        Nearest input points a local-point denoiser reads (0: none; it then also takes
        the encoder's input, see :func:`spacemesh.runtime.backend.denoiser_fn`).
    large_meshes : {"tokens", "split"}
        How ``start=points`` makes more vertices than ``max_vertices``: all of them as
        tokens of the connectivity network (up to a cap), or ``max_vertices`` tokens and
        edge splits (:mod:`spacemesh.runtime.large`; ``manifest["sampler"]["large_meshes"]``).
    retry_seeds : int
        Seeds tried beyond a request's own when none of its meshes has as many pieces as
        the points and faces that do not cross (``manifest["sampler"]["retry_seeds"]``, at
        most :data:`MAX_RETRY_SEEDS`; 0, the default, tries
        none), topping a request up to ``1 + retry_seeds`` seeds in all
        (:meth:`retries_for`). The decode's topology and crossings depend on the seed;
        see docs/GEOMETRY.md.
    """

    n_points: int
    max_vertices: int
    normals: bool
    schedule: NoiseSchedule
    method: str
    steps: int
    decode: DecodeOptions
    vertex_spacing: float = DUPLICATE_TOLERANCE
    start: str = "noise"
    start_time: float = 0.0
    vertices: int = DEFAULT_VERTICES
    feature_boost: float = 0.0
    geometry: GeometryOptions = field(default_factory=GeometryOptions)
    local_points: int = 0
    large_meshes: str = DEFAULT_LARGE_MESHES
    retry_seeds: int = 0

    def retries_for(self, samples: int) -> int:
        """The retry seeds a request of ``samples`` seeds of its own may add when none
        of them passes the topology check: enough for ``1 + retry_seeds`` seeds in all,
        so a request that already ran that many adds none (its cost stays that of the
        seeds it asked for).

        Parameters
        ----------
        samples : int
            The request's own seeds.

        Returns
        -------
        int
            From 0 to :attr:`retry_seeds`.
        """
        return max(0, self.retry_seeds + 1 - samples)

    @classmethod
    def from_config(cls, config: dict[str, Any], betas: Sequence[float] | None = None,
                    reduction_params: dict[str, Any] | None = None) -> ModelSpec:
        """From a :class:`spacemesh.nn.config.ModelConfig` dict.

        Parameters
        ----------
        config : dict
        betas : sequence of float, optional
            The trained schedule (recomputed from the config when None).
        reduction_params : dict, optional
            Weights of a ``concat`` permutation reduction.

        Returns
        -------
        ModelSpec
        """
        diffusion = config["diffusion"]
        con = config["connectivity"]
        schedule = (
            NoiseSchedule(np.asarray(betas, dtype=np.float64)) if betas is not None
            else NoiseSchedule.from_config(diffusion["schedule"], diffusion["timesteps"])
        )
        params: dict[str, FloatArray] | None = (
            {k: np.asarray(v, np.float64) for k, v in reduction_params.items()}
            if reduction_params else None
        )
        return cls(
            n_points=int(config["encoder"]["n_points"]),
            max_vertices=int(config["max_vertices"]),
            normals=bool(config["encoder"]["normals"]),
            schedule=schedule,
            method=str(diffusion["sampler"]),
            steps=int(diffusion["steps"]),
            decode=DecodeOptions(distance=con["distance"], n_space=int(con["n_space"]),
                                 reduction=con["reduction"], reduction_params=params),
            local_points=int(config["denoiser"].get("local_points", 0)),
        )

    @classmethod
    def from_manifest(cls, manifest: dict[str, Any]) -> ModelSpec:
        """From a model repository's ``manifest.json``."""
        spec = cls.from_config(
            manifest["config"], manifest["schedule"]["betas"],
            manifest.get("embedding", {}).get("reduction_params"),
        )
        sampler = manifest.get("sampler", {})
        decode = replace(spec.decode, **decode_changes(manifest.get("decode", {})))
        return replace(
            spec, vertex_spacing=float(sampler.get("vertex_spacing", DUPLICATE_TOLERANCE)),
            decode=decode, start=str(sampler.get("start", "noise")),
            start_time=float(sampler.get("start_time", 0.0)),
            vertices=int(sampler.get("vertices", DEFAULT_VERTICES)),
            feature_boost=float(sampler.get("feature_boost", 0.0)),
            geometry=GeometryOptions.from_section(manifest.get("geometry", {})),
            large_meshes=check_large_meshes(
                str(sampler.get("large_meshes", DEFAULT_LARGE_MESHES))),
            retry_seeds=check_retry_seeds(sampler.get("retry_seeds", 0)),
        )



__all__ = ["DEFAULT_VERTICES", "DUPLICATE_TOLERANCE", "MAX_RETRY_SEEDS", "ModelSpec",
           "check_retry_seeds"]
