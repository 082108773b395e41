"""Checkpoints: model, optimiser, step and random state in one ``torch.save`` file.

Everything stored is a tensor or a plain Python value, so checkpoints load with
``torch.load(..., weights_only=True)`` (no pickled code is ever executed). The config and
the numpy generator state are stored as JSON strings.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import torch

from spacemesh.nn.config import ModelConfig

#: File name of the newest checkpoint in a run's ``checkpoints`` folder.
LAST = "last.pt"


def checkpoint_dir(run: str | Path) -> Path:
    """``RUN/checkpoints``."""
    return Path(run) / "checkpoints"


def save_checkpoint(
    path: str | Path,
    *,
    model: torch.nn.Module,
    optimizer: torch.optim.Optimizer | None,
    step: int,
    config: ModelConfig,
    rng: np.random.Generator | None = None,
    torch_generator: torch.Generator | None = None,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Write a checkpoint atomically (temporary file, then rename).

    Parameters
    ----------
    path : path
    model : torch.nn.Module
        The bare model (not a DDP wrapper).
    optimizer : torch.optim.Optimizer, optional
    step : int
        Diffusion steps done.
    config : ModelConfig
    rng : numpy.random.Generator, optional
        The batch sampler's generator.
    torch_generator : torch.Generator, optional
        The generator of diffusion timesteps and noise (default: torch's global state).
    extra : dict, optional
        JSON-ready values (elapsed time, data card ...), stored as a JSON string.

    Returns
    -------
    Path
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {
        "format": "spacemesh-checkpoint",
        "step": int(step),
        "config": json.dumps(config.to_dict()),
        "model": model.state_dict(),
        "optimizer": optimizer.state_dict() if optimizer is not None else {},
        "numpy_rng": json.dumps(rng.bit_generator.state) if rng is not None else "",
        "torch_rng": (torch_generator.get_state() if torch_generator is not None
                      else torch.get_rng_state()),
        "extra": json.dumps(extra or {}),
    }
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)
    return path


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """Read a checkpoint with ``weights_only=True``.

    Parameters
    ----------
    path : path
    map_location : device

    Returns
    -------
    dict
        ``step`` (int), ``config`` (ModelConfig), ``model`` and ``optimizer`` state dicts,
        ``numpy_rng`` (dict or None), ``torch_rng`` (tensor), ``extra`` (dict).
    """
    state = torch.load(Path(path), map_location=map_location, weights_only=True)
    if state.get("format") != "spacemesh-checkpoint":
        raise ValueError(f"{path} is not a SpaceMesh checkpoint")
    state["config"] = ModelConfig.from_dict(json.loads(state["config"]))
    state["numpy_rng"] = json.loads(state["numpy_rng"]) if state["numpy_rng"] else None
    state["extra"] = json.loads(state["extra"])
    return state


def latest_checkpoint(run: str | Path) -> Path | None:
    """``RUN/checkpoints/last.pt`` if it exists, else None."""
    path = checkpoint_dir(run) / LAST
    return path if path.is_file() else None


def resolve_checkpoint(path: str | Path) -> Path:
    """A checkpoint file as given, or a run folder's ``checkpoints/last.pt``.

    Raises
    ------
    FileNotFoundError
        Neither a file nor a run folder with a last checkpoint.
    """
    path = Path(path)
    if path.is_dir():
        found = latest_checkpoint(path)
        if found is None:
            raise FileNotFoundError(f"{path} has no checkpoints/last.pt")
        return found
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such run folder or checkpoint")
    return path


def restore_rng(rng: np.random.Generator, state: dict | None) -> None:
    """Set ``rng``'s bit generator state from a checkpoint (no-op for None)."""
    if state is not None:
        rng.bit_generator.state = state
