"""Export the three networks to ONNX with the torch dynamo exporter.

Each graph is a thin wrapper with flat tensor inputs and outputs (names in
:mod:`spacemesh.runtime.backend`), exported at opset :data:`OPSET` with the weights
inside the file (``external_data=False``) and dynamic batch, point and vertex counts.
The sampler loop is not in any graph: the denoiser graph is one step.
"""

from __future__ import annotations

import contextlib
import io
import logging
import warnings
from pathlib import Path

import torch
from torch import Tensor, nn

from spacemesh.nn.model import SpaceMeshModel
from spacemesh.runtime.backend import (
    CONNECTIVITY_INPUTS,
    CONNECTIVITY_OUTPUTS,
    DENOISER_INPUTS,
    DENOISER_POINTS,
    ENCODER_INPUTS,
    volume_names,
)

#: ONNX opset of the exported graphs.
OPSET = 20

#: File name of each graph in a model repository version folder.
GRAPH_FILES = {
    "encoder": "encoder.onnx",
    "denoiser": "denoiser.onnx",
    "connectivity": "connectivity.onnx",
}


class EncoderGraph(nn.Module):
    """``points (B, P, 3|6) -> volume_0 .. volume_{L-1}``."""

    def __init__(self, model: SpaceMeshModel) -> None:
        super().__init__()
        self.encoder = model.encoder

    def forward(self, points: Tensor) -> tuple[Tensor, ...]:
        return tuple(self.encoder(points))


class DenoiserGraph(nn.Module):
    """``x_t (B, N, 4), t (B,) int64, volumes -> eps (B, N, 4)``."""

    def __init__(self, model: SpaceMeshModel) -> None:
        super().__init__()
        self.denoiser = model.denoiser

    def forward(self, x_t: Tensor, t: Tensor, volumes: tuple[Tensor, ...]) -> Tensor:
        return self.denoiser(x_t, t, list(volumes))


class LocalDenoiserGraph(nn.Module):
    """``x_t (B, N, 4), t (B,) int64, volumes, points (B, P, 3|6) -> eps (B, N, 4)``: a
    local-point denoiser, whose nearest-point lookup runs inside the graph."""

    def __init__(self, model: SpaceMeshModel) -> None:
        super().__init__()
        self.denoiser = model.denoiser

    def forward(self, x_t: Tensor, t: Tensor, volumes: tuple[Tensor, ...], points: Tensor
                ) -> Tensor:
        return self.denoiser(x_t, t, list(volumes), points)


class ConnectivityGraph(nn.Module):
    """``vertices (B, N, 3), valid (B, N) bool, volumes -> x, root, prev, next, tau``."""

    def __init__(self, model: SpaceMeshModel) -> None:
        super().__init__()
        self.connectivity = model.connectivity

    def forward(
        self, vertices: Tensor, valid: Tensor, volumes: tuple[Tensor, ...]
    ) -> tuple[Tensor, ...]:
        return self.connectivity(vertices, valid, list(volumes))


def example_inputs(model: SpaceMeshModel, batch: int = 2) -> dict[str, tuple]:
    """Example arguments of each graph (sizes chosen so that no dimension specialises)."""
    config = model.config
    channels = 6 if config.encoder.normals else 3
    gen = torch.Generator().manual_seed(0)
    points = torch.rand(batch, 37, channels, generator=gen) * 2 - 1
    with torch.no_grad():
        volumes = tuple(model.encoder(points))
    n = 11
    x_t = torch.randn(batch, n, 4, generator=gen)
    t = torch.tensor([3, 5] * batch, dtype=torch.int64)[:batch]
    vertices = torch.rand(batch, n, 3, generator=gen) * 2 - 1
    valid = torch.ones(batch, n, dtype=torch.bool)
    valid[0, -3:] = False
    if config.denoiser.local_points:  # enough points for the top-k
        cloud = torch.rand(batch, config.denoiser.local_points + 29, channels, generator=gen)
        denoiser = (x_t, t, volumes, cloud * 2 - 1)
    else:
        denoiser = (x_t, t, volumes)
    return {
        "encoder": (points,),
        "denoiser": denoiser,
        "connectivity": (vertices, valid, volumes),
    }


#: Loggers of the exporter that report routine events as warnings.
_QUIET_LOGGERS = ("torch.onnx", "onnx_ir", "onnxscript")


def _export(module: nn.Module, args: tuple, path: Path, input_names, output_names,
            dynamic_shapes, opset: int) -> None:
    loggers = [logging.getLogger(name) for name in _QUIET_LOGGERS]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.ERROR)
    try:
        _export_quietly(module, args, path, input_names, output_names, dynamic_shapes, opset)
    finally:
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)


def _export_quietly(module: nn.Module, args: tuple, path: Path, input_names, output_names,
                    dynamic_shapes, opset: int) -> None:
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        program = torch.onnx.export(
            module, args, dynamo=True, opset_version=opset, external_data=False,
            input_names=list(input_names), output_names=list(output_names),
            dynamic_shapes=dynamic_shapes, verbose=False, optimize=True,
        )
    program.save(str(path), external_data=False)


def export_onnx(
    model: SpaceMeshModel, directory: str | Path, *, opset: int = OPSET,
    graphs: tuple[str, ...] = tuple(GRAPH_FILES),
) -> dict[str, Path]:
    """Write ``encoder.onnx``, ``denoiser.onnx`` and ``connectivity.onnx``.

    Parameters
    ----------
    model : SpaceMeshModel
        Moved to CPU float32 eval mode for the export.
    directory : path
    opset : int
        At least 20.
    graphs : tuple of str
        The graphs to write (a connectivity-only run writes ``("connectivity",)``; its
        encoder may be the base's onnxruntime graph, which is only called).

    Returns
    -------
    dict
        Graph name to file path (of the graphs written).
    """
    if opset < 20:
        raise ValueError("opset must be 20 or higher")
    unknown = set(graphs) - set(GRAPH_FILES)
    if unknown:
        raise ValueError(f"unknown graphs: {', '.join(sorted(unknown))}")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    model = model.to("cpu").float().eval()
    n_volumes = len(model.config.encoder.resolutions)
    vols = volume_names(n_volumes)
    args = example_inputs(model)
    batch = torch.export.Dim("batch", min=1, max=4096)
    points = torch.export.Dim("points", min=1, max=1 << 20)
    vertices = torch.export.Dim("vertices", min=2, max=1 << 16)
    vol_shapes = tuple({0: batch} for _ in range(n_volumes))
    paths = {name: directory / GRAPH_FILES[name] for name in graphs}
    if "encoder" in paths:
        _export(
            EncoderGraph(model), args["encoder"], paths["encoder"], ENCODER_INPUTS, vols,
            {"points": {0: batch, 1: points}}, opset,
        )
    if "denoiser" in paths and model.config.denoiser.local_points:
        cloud = torch.export.Dim("cloud", min=model.config.denoiser.local_points, max=1 << 20)
        _export(
            LocalDenoiserGraph(model), args["denoiser"], paths["denoiser"],
            [*DENOISER_INPUTS, *vols, DENOISER_POINTS], ["eps"],
            {"x_t": {0: batch, 1: vertices}, "t": {0: batch}, "volumes": vol_shapes,
             "points": {0: batch, 1: cloud}}, opset,
        )
    elif "denoiser" in paths:
        _export(
            DenoiserGraph(model), args["denoiser"], paths["denoiser"],
            [*DENOISER_INPUTS, *vols], ["eps"],
            {"x_t": {0: batch, 1: vertices}, "t": {0: batch}, "volumes": vol_shapes}, opset,
        )
    if "connectivity" in paths:
        _export(
            ConnectivityGraph(model), args["connectivity"], paths["connectivity"],
            [*CONNECTIVITY_INPUTS, *vols], CONNECTIVITY_OUTPUTS,
            {"vertices": {0: batch, 1: vertices}, "valid": {0: batch, 1: vertices},
             "volumes": vol_shapes},
            opset,
        )
    return paths
