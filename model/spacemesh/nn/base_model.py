"""A trained model repository as the frozen base of a connectivity-only (or a
diffusion-only) run.

Training the connectivity network is the slow part of SpaceMesh (the paper trains it ten
times as often as the diffusion model). ``spacemesh train --base MODEL_REPO`` trains a
new connectivity network on the frozen encoder of an exported model: the encoder runs
in onnxruntime (:class:`OnnxEncoder`, a drop-in for the torch encoder that has no
parameters), the base's denoiser is kept as it is, and export copies both ONNX graphs
unchanged next to the new connectivity graph. A diffusion-only run
(``TrainConfig.diffusion_only``) on a base trains a new denoiser instead, and export keeps
the base's encoder and connectivity graphs.

:class:`BaseModel` reads and verifies the repository and says what the run inherits.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from spacemesh.nn.config import ModelConfig
from spacemesh.runtime.backend import volume_names
from spacemesh.runtime.repository import (
    MANIFEST,
    ModelRepositoryError,
    SessionOptions,
    create_session,
    resolve_version_dir,
    verify_files,
)


@dataclass(frozen=True)
class BaseModel:
    """A verified model repository version.

    Attributes
    ----------
    path : Path
        The version folder.
    manifest : dict
    """

    path: Path
    manifest: dict[str, Any]

    @classmethod
    def load(cls, path: str | Path) -> BaseModel:
        """Read ``path`` (a version, model or repository folder) and check every sha256.

        Raises
        ------
        ValueError
            No model repository there, an unreadable manifest, or a file that does not
            match it.
        """
        try:
            directory = resolve_version_dir(path)
            manifest = json.loads((directory / MANIFEST).read_text())
            verify_files(directory, manifest)
            ModelConfig.from_dict(manifest["config"])
        except (ModelRepositoryError, OSError, ValueError, KeyError, TypeError) as error:
            raise ValueError(f"base model {path}: {error}") from error
        return cls(directory.resolve(), manifest)

    @property
    def config(self) -> ModelConfig:
        """The base's configuration."""
        return ModelConfig.from_dict(self.manifest["config"])

    def graph_path(self, graph: str) -> Path:
        """The ONNX file of ``graph`` (``encoder``, ``denoiser`` or ``connectivity``)."""
        return self.path / self.manifest["graphs"][graph]["file"]

    def merged_config(self, config: ModelConfig) -> ModelConfig:
        """``config``'s connectivity network and training settings on the base's encoder,
        denoiser, diffusion and vertex count (the parts the run inherits); for a
        diffusion-only run (``config.train.diffusion_only``), ``config``'s denoiser on
        the base's encoder, connectivity network, diffusion and vertex count."""
        if config.train.diffusion_only:
            return replace(self.config, name=config.name, denoiser=config.denoiser,
                           train=config.train)
        return replace(self.config, name=config.name, connectivity=config.connectivity,
                       train=config.train)

    def frozen_graphs(self, config: ModelConfig) -> tuple[str, str]:
        """The base graphs a run on it keeps (export copies them byte for byte): the
        encoder, and the denoiser or (diffusion-only) the connectivity network."""
        return ("encoder", "connectivity" if config.train.diffusion_only else "denoiser")

    def card(self) -> dict[str, Any]:
        """What a run records about its base: where it is, which files, how it was made."""
        return {
            "path": str(self.path),
            "name": self.manifest.get("name"),
            "version": self.manifest.get("version"),
            "files": {f: e["sha256"] for f, e in self.manifest["files"].items()},
            "data": self.manifest.get("data", {}),
            "training": self.manifest.get("training", {}),
        }


class OnnxEncoder(nn.Module):
    """The base's encoder graph in onnxruntime, called like the torch encoder.

    It has no parameters (nothing of it trains) and returns CPU-computed volumes on the
    device of its input.

    Parameters
    ----------
    path : path
        ``encoder.onnx``.
    threads : int
        onnxruntime intra-op threads (0: its default).
    """

    def __init__(self, path: str | Path, threads: int = 0) -> None:
        super().__init__()
        self.session = create_session(Path(path), SessionOptions(intra_op_threads=threads))
        self.names = volume_names(len(self.session.get_outputs()))

    def forward(self, points: Tensor) -> list[Tensor]:
        """Feature volumes ``(B, C_r, R_r, R_r, R_r)`` of ``points`` ``(B, P, 3 or 6)``."""
        array = np.ascontiguousarray(points.detach().float().cpu().numpy())
        volumes = self.session.run(self.names, {"points": array})
        return [torch.from_numpy(v).to(points.device) for v in volumes]
