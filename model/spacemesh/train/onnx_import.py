"""Torch weights back from exported connectivity and denoiser graphs, to fine-tune a
shipped model.

A model repository holds ONNX graphs, not checkpoints, and training runs are never
committed, so a shipped model would otherwise be a dead end for training. The dynamo
exporter keeps most parameters as initializers under their own names; it folds the
rest into constants that its node metadata still names: every ``nn.Linear`` becomes a
``MatMul`` with the transposed weight and an ``Add`` of the bias (the fx node of the
``MatMul`` names both parameters), the distance prior's ``log_slope`` is folded into
``exp(log_slope)`` shaped ``(1, H, 1, 1)`` (the one ``Mul`` constant of that shape), and
``tau`` is an initializer of its own. :func:`graph_weights` reads them all back and
:func:`load_connectivity` and :func:`load_denoiser` check the result against the graph
itself (the same outputs in onnxruntime and in torch), so a graph this reader does not
understand is refused, not half-loaded.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import torch

from spacemesh.nn.connectivity_net import ConnectivityNet

#: Prefix of the connectivity network's parameters in the exported graph.
PREFIX = "connectivity."
#: Largest output difference (relative to the output scale) accepted after loading.
PARITY_TOLERANCE = 1e-4

_PARAM = re.compile(r"%p_(\w+)")


def _initializers(graph) -> dict[str, np.ndarray]:
    from onnx import numpy_helper

    return {i.name: numpy_helper.to_array(i) for i in graph.initializer}


def graph_weights(path: str | Path, net: torch.nn.Module, prefix: str
                  ) -> dict[str, torch.Tensor]:
    """The state dict of ``net`` (an instance of the exported architecture) read from an
    exported graph whose parameters are named ``prefix + name``.

    Parameters
    ----------
    path : path
        An exported graph (``connectivity.onnx``, ``denoiser.onnx``).
    net : torch.nn.Module
        Built from the same config; it provides the parameter names and shapes.
    prefix : str
        The network's attribute in the exported wrapper, with a dot (``"denoiser."``).

    Returns
    -------
    dict
        Parameter name -> tensor, for every entry of ``net.state_dict()``.

    Raises
    ------
    ValueError
        A parameter is missing from the graph or has another shape there.
    """
    import onnx

    graph = onnx.load(str(path)).graph
    values = _initializers(graph)
    wanted = net.state_dict()
    # flattened names in the fx metadata ('backbone_blocks_0_attn_qkv_weight')
    flat = {(prefix + k).replace(".", "_"): k for k in wanted}
    found: dict[str, np.ndarray] = {}
    for key in wanted:
        if prefix + key in values:
            found[key] = values[prefix + key]
    consumers: dict[str, list] = {}
    for node in graph.node:
        for name in node.input:
            consumers.setdefault(name, []).append(node)
    for node in graph.node:
        if node.op_type != "MatMul" or node.input[1] not in values:
            continue
        meta = {p.key: p.value for p in node.metadata_props}
        params = [flat.get(p) for p in _PARAM.findall(meta.get("pkg.torch.onnx.fx_node", ""))]
        params = [p for p in params if p is not None]
        weights = [p for p in params if p.endswith("weight")]
        if len(weights) != 1:
            continue
        found[weights[0]] = values[node.input[1]].T
        bias = weights[0][: -len("weight")] + "bias"
        if bias in wanted and bias not in found:
            adds = [n for n in consumers.get(node.output[0], []) if n.op_type == "Add"]
            constants = [i for n in adds for i in n.input if i in values]
            if len(constants) == 1:
                found[bias] = values[constants[0]]
    if "log_slope" in wanted and "log_slope" not in found:
        heads = wanted["log_slope"].shape[0]
        folded = [v for v in values.values() if v.shape == (1, heads, 1, 1) and (v > 0).all()]
        if len(folded) == 1:
            found["log_slope"] = np.log(folded[0].reshape(-1))
    if "tau" in wanted and "tau" in values:
        found["tau"] = values["tau"].reshape(wanted["tau"].shape)
    state = {}
    for key, reference in wanted.items():
        if key not in found:
            raise ValueError(f"{path}: no weights for {prefix}{key} in the graph")
        value = np.asarray(found[key], dtype=np.float32)
        if tuple(value.shape) != tuple(reference.shape):
            raise ValueError(f"{path}: {prefix}{key} has shape {value.shape} in the "
                             f"graph, {tuple(reference.shape)} in the config's network")
        state[key] = torch.from_numpy(value.copy())
    return state


@torch.no_grad()
def load_connectivity(path: str | Path, net: ConnectivityNet, volumes: list[torch.Tensor]
                      ) -> float:
    """Load a ``connectivity.onnx``'s weights into ``net`` and check it reproduces the
    graph.

    Parameters
    ----------
    path : path
    net : ConnectivityNet
        Changed in place.
    volumes : list of (1, C_r, R_r, R_r, R_r) tensors
        Encoder volumes of some shape, for the check (the graph's inputs).

    Returns
    -------
    float
        The largest output difference, relative to the outputs' scale.

    Raises
    ------
    ValueError
        A weight is missing, or the loaded network does not reproduce the graph.
    """
    from spacemesh.runtime.backend import CONNECTIVITY_OUTPUTS

    generator = torch.Generator().manual_seed(0)
    vertices = torch.rand(1, 40, 3, generator=generator) * 2 - 1
    valid = torch.ones(1, 40, dtype=torch.bool)
    valid[0, 35:] = False
    return _read_back(path, net, PREFIX, {"vertices": vertices, "valid": valid}, volumes,
                      list(CONNECTIVITY_OUTPUTS))


def _read_back(path: str | Path, net: torch.nn.Module, prefix: str,
               inputs: dict[str, torch.Tensor], volumes: list[torch.Tensor],
               outputs: list[str] | None = None) -> float:
    """Load ``net``'s weights from the graph at ``path`` (:func:`graph_weights`) and
    check that ``net(*inputs, volumes)`` reproduces the graph's ``outputs`` (all of them
    when None, in ``net``'s order) in onnxruntime (:func:`_check_parity`)."""
    import onnxruntime as ort

    from spacemesh.runtime.backend import volume_names

    net.load_state_dict(graph_weights(path, net, prefix))
    was_training = net.training
    net.eval()
    ours = net(*inputs.values(), volumes)
    if isinstance(ours, torch.Tensor):
        ours = [ours]
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    feeds = {name: value.numpy() for name, value in inputs.items()}
    feeds.update(zip(volume_names(len(volumes)), (v.numpy() for v in volumes), strict=True))
    theirs = session.run(outputs, feeds)
    net.train(was_training)
    return _check_parity(path, ours, theirs)


def _check_parity(path: str | Path, ours, theirs) -> float:
    """The largest difference between torch outputs ``ours`` and onnxruntime outputs
    ``theirs``, relative to each output's scale; above :data:`PARITY_TOLERANCE` the
    weights read back are refused."""
    worst = 0.0
    for a, b in zip(ours, theirs, strict=True):
        a = a.detach().reshape(b.shape).numpy()
        scale = max(float(np.abs(b).max()), 1.0)
        worst = max(worst, float(np.abs(a - b).max()) / scale)
    if worst > PARITY_TOLERANCE:
        raise ValueError(f"{path}: the weights read back do not reproduce the graph "
                         f"(relative difference {worst:.2e})")
    return worst


@torch.no_grad()
def load_denoiser(path: str | Path, net: torch.nn.Module, volumes: list[torch.Tensor]
                  ) -> float:
    """Load a volumes-only ``denoiser.onnx``'s weights into ``net`` (a
    :class:`spacemesh.nn.denoiser.VertexDenoiser` without local points) and check that it
    reproduces the graph.

    Parameters
    ----------
    path : path
    net : VertexDenoiser
        Changed in place.
    volumes : list of (1, C_r, R_r, R_r, R_r) tensors
        Encoder volumes of some shape, for the check (the graph's inputs).

    Returns
    -------
    float
        The largest output difference, relative to the output's scale.

    Raises
    ------
    ValueError
        A weight is missing, or the loaded network does not reproduce the graph.
    """
    from spacemesh.runtime.backend import DENOISER_INPUTS

    if getattr(net, "local_points", 0):
        raise ValueError("load_denoiser reads a volumes-only denoiser; graft the result "
                         "into a local-point one (spacemesh.nn.denoiser.graft_denoiser)")
    generator = torch.Generator().manual_seed(0)
    x_t = torch.randn(1, 40, 4, generator=generator)  # (1, N, 4)
    t = torch.tensor([17], dtype=torch.int64)
    inputs = dict(zip(DENOISER_INPUTS, (x_t, t), strict=True))
    return _read_back(path, net, "denoiser.", inputs, volumes)


def is_model_version(path: str | Path) -> bool:
    """Whether ``path`` is a model version folder (it holds a ``manifest.json``)."""
    return (Path(path) / "manifest.json").is_file()


def init_from_repository(path: str | Path) -> dict:
    """What ``spacemesh train --init-from`` needs from an exported connectivity-only
    model: its config, its connectivity network's weights (read back and checked by
    :func:`load_connectivity`) and its base, in the layout of
    :func:`spacemesh.train.checkpoint.load_checkpoint`.

    The base is the model its training section names, looked up next to it
    (``ROOT/NAME/VERSION``) and checked against the files the model was trained on.

    Parameters
    ----------
    path : path
        A version folder, e.g. ``models/spacemesh-small/6``.

    Returns
    -------
    dict
        ``config`` (ModelConfig), ``connectivity`` (state dict), ``step`` (0), ``extra``
        (``base`` card, ``data`` card, ``train_seconds``) and ``path``.

    Raises
    ------
    ValueError
        Not a connectivity-only model, its base is missing or changed, or its graph
        cannot be read back.
    """
    from spacemesh.nn.base_model import BaseModel, OnnxEncoder
    from spacemesh.nn.config import ModelConfig
    from spacemesh.nn.model import model_from_config
    from spacemesh.runtime.repository import verified_manifest

    directory = Path(path)
    manifest = verified_manifest(directory)
    training = manifest.get("training", {})
    stored = training.get("base")
    if stored is None:
        raise ValueError(f"{directory}: only a connectivity-only model (trained with --base) "
                         "can be fine-tuned from its repository; train a full model from "
                         "its run folder")
    base_dir = directory.parent.parent / str(stored["name"]) / str(stored["version"])
    base = BaseModel.load(base_dir)
    now = {f: e["sha256"] for f, e in base.manifest["files"].items()}
    for graph in ("encoder.onnx", "denoiser.onnx"):
        if now.get(graph) != stored["files"].get(graph):
            raise ValueError(f"{directory}: its base {base_dir} changed since training "
                             f"({graph})")
    config = ModelConfig.from_dict(manifest["config"])
    net = model_from_config(config).connectivity
    encoder = OnnxEncoder(base.graph_path("encoder"))
    channels = 6 if config.encoder.normals else 3
    points = torch.rand(1, config.encoder.n_points, channels,
                        generator=torch.Generator().manual_seed(0)) * 2 - 1
    with torch.no_grad():
        volumes = list(encoder(points))
    load_connectivity(directory / "connectivity.onnx", net, volumes)
    return {
        "config": config,
        "connectivity": net.state_dict(),
        "step": 0,
        "extra": {"base": base.card(), "data": manifest.get("data", {}),
                  "train_seconds": float(training.get("seconds", 0.0))},
        "path": directory,
    }
