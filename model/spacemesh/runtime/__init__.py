"""The inference runtime: numpy + onnxruntime only (never torch), used by the service.

- :mod:`~spacemesh.runtime.repository`: load and verify a model repository
  (:class:`ModelRepository`, :data:`DEFAULT_MODEL_DIR`).
- :mod:`~spacemesh.runtime.pipeline`: :class:`MeshGenerator` (point cloud to mesh),
  :class:`GenerateRequest`, :class:`GenerateResult`.
- :mod:`~spacemesh.runtime.sampler` and :mod:`~spacemesh.runtime.schedule`: the diffusion
  sampler loop (DDPM and respaced DDIM) in numpy.
- :mod:`~spacemesh.runtime.backend`: the graph interface and its onnxruntime backend.
"""

from spacemesh.runtime.pipeline import MeshGenerator
from spacemesh.runtime.repository import (
    DEFAULT_MODEL_DIR,
    ModelRepository,
    ModelRepositoryError,
    default_model_dir,
)
from spacemesh.runtime.request import GenerateRequest, GenerateResult
from spacemesh.runtime.spec import ModelSpec

__all__ = [
    "DEFAULT_MODEL_DIR",
    "GenerateRequest",
    "GenerateResult",
    "MeshGenerator",
    "ModelRepository",
    "ModelRepositoryError",
    "ModelSpec",
    "default_model_dir",
]
