"""Write a model repository that the runtime loads without torch.

Layout (Triton style)::

    ROOT/NAME/VERSION/encoder.onnx
    ROOT/NAME/VERSION/denoiser.onnx
    ROOT/NAME/VERSION/connectivity.onnx
    ROOT/NAME/VERSION/manifest.json

``manifest.json`` keys:

``format``, ``format_version``
    ``"spacemesh-model"``, 1.
``name``, ``version``
    As in the path.
``config``
    The full :class:`spacemesh.nn.config.ModelConfig` as a dict.
``inputs``
    ``n_points``, ``max_vertices``, ``normals``: what a request feeds the encoder.
``schedule``
    ``kind``, ``timesteps`` and the trained ``betas`` (list of T floats).
``sampler``
    Default ``method`` and ``steps``.
``embedding``
    ``adjacency_dim``, ``n_space``, ``permutation_dim``, ``distance``, ``reduction``,
    ``sinkhorn_iters`` (and ``reduction_params`` for a learned reduction).
``graphs``
    Per graph: ``file``, ``inputs`` and ``outputs`` (names, see
    :mod:`spacemesh.runtime.backend`).
``files``
    Per file: ``sha256`` and ``bytes``.
``onnx``
    ``opset``, ``exporter``, ``torch`` version.
``data``
    The data card (dataset, generator, seed, style, vertex range, counts).
``training``
    Steps, seconds, device, world size, threads.
``metrics``
    Held-out metrics (see :mod:`spacemesh.train.evaluate`).
``golden``
    Each graph's raw outputs for a fixed input, checked when the model loads (see
    :mod:`spacemesh.runtime.golden`; written by :func:`spacemesh.export.golden.record_golden`).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from spacemesh.export.golden import record_golden
from spacemesh.export.manifest import update_manifest, write_manifest
from spacemesh.export.onnx_export import GRAPH_FILES, OPSET, export_onnx
from spacemesh.geometry.policy import decode_changes, decode_section
from spacemesh.geometry.stage import geometry_section
from spacemesh.nn.base_model import BaseModel, OnnxEncoder
from spacemesh.nn.model import SpaceMeshModel
from spacemesh.permutation import SINKHORN_ITERS
from spacemesh.runtime.backend import (
    CONNECTIVITY_INPUTS,
    CONNECTIVITY_OUTPUTS,
    DENOISER_INPUTS,
    DENOISER_POINTS,
    ENCODER_INPUTS,
    volume_names,
)
from spacemesh.runtime.golden import SECTION as SECTION_GOLDEN
from spacemesh.runtime.options import POINTS_START, RELEASE_RETRY_SEEDS
from spacemesh.runtime.repository import (
    FORMAT,
    FORMAT_VERSION,
    MANIFEST,
    sha256_file,
    verified_manifest,
)


def graph_signatures(n_volumes: int, local_points: bool = False) -> dict[str, dict[str, Any]]:
    """File, input and output names of each graph (``local_points``: the denoiser also
    takes the points)."""
    vols = volume_names(n_volumes)
    points = [DENOISER_POINTS] if local_points else []
    return {
        "encoder": {"file": GRAPH_FILES["encoder"], "inputs": list(ENCODER_INPUTS),
                    "outputs": vols},
        "denoiser": {"file": GRAPH_FILES["denoiser"],
                     "inputs": [*DENOISER_INPUTS, *vols, *points], "outputs": ["eps"]},
        "connectivity": {"file": GRAPH_FILES["connectivity"],
                         "inputs": [*CONNECTIVITY_INPUTS, *vols],
                         "outputs": list(CONNECTIVITY_OUTPUTS)},
    }


def build_manifest(
    model: SpaceMeshModel,
    directory: Path,
    *,
    name: str,
    version: int,
    opset: int = OPSET,
    data: dict[str, Any] | None = None,
    training: dict[str, Any] | None = None,
    metrics: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The manifest of a version folder whose graphs are already written.

    Parameters
    ----------
    model : SpaceMeshModel
    directory : Path
        The version folder (file hashes are computed from it).
    name : str
    version : int
    opset : int
    data, training, metrics : dict, optional

    Returns
    -------
    dict
    """
    config = model.config
    con = config.connectivity
    params = model.reduction.numpy_params()
    embedding = {
        "adjacency_dim": con.adjacency_dim, "n_space": con.n_space,
        "permutation_dim": con.permutation_dim, "distance": con.distance,
        "reduction": con.reduction, "sinkhorn_iters": SINKHORN_ITERS,
    }
    if params is not None:
        embedding["reduction_params"] = {k: v.tolist() for k, v in params.items()}
    files = {
        f: {"sha256": sha256_file(directory / f), "bytes": (directory / f).stat().st_size}
        for f in GRAPH_FILES.values()
    }
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "name": name,
        "version": int(version),
        "config": config.to_dict(),
        "inputs": {"n_points": config.encoder.n_points, "max_vertices": config.max_vertices,
                   "normals": config.encoder.normals},
        "schedule": {"kind": config.diffusion.schedule, "timesteps": config.diffusion.timesteps,
                     "betas": model.diffusion.schedule.betas.tolist()},
        "sampler": {"method": config.diffusion.sampler, "steps": config.diffusion.steps,
                    **POINTS_START},
        "geometry": geometry_section(),
        "embedding": embedding,
        "graphs": graph_signatures(len(config.encoder.resolutions),
                                   bool(config.denoiser.local_points)),
        "files": files,
        "onnx": {"opset": opset, "exporter": "torch.onnx.export(dynamo=True)",
                 "torch": torch.__version__.split("+")[0]},
        "data": data or {},
        "training": training or {},
        "metrics": metrics or {},
    }


def write_model_repository(
    model: SpaceMeshModel,
    root: str | Path,
    *,
    name: str,
    version: int = 1,
    opset: int = OPSET,
    data: dict[str, Any] | None = None,
    training: dict[str, Any] | None = None,
    metrics: dict[str, Any] | None = None,
    overwrite: bool = True,
    base: BaseModel | None = None,
) -> Path:
    """Export the graphs and write ``ROOT/NAME/VERSION`` with its manifest.

    Parameters
    ----------
    model : SpaceMeshModel
    root : path
        Repository root.
    name : str
    version : int
    opset : int
    data, training, metrics : dict, optional
        Data card, training record and held-out metrics for the manifest.
    overwrite : bool
        Replace an existing version folder.
    base : BaseModel, optional
        A connectivity-only run's base: its encoder and denoiser graphs are copied
        byte for byte and only the connectivity graph is exported (a diffusion-only
        run's: its encoder and connectivity graphs, and only the denoiser is exported).

    Returns
    -------
    Path
        The version folder.
    """
    directory = Path(root) / name / str(version)
    if base is not None and directory.resolve() == base.path:
        raise ValueError(f"{directory} is the run's base model; export to another version")
    if directory.exists():
        if not overwrite:
            raise FileExistsError(f"{directory} exists")
        shutil.rmtree(directory)
    if base is None:
        export_onnx(model, directory, opset=opset)
    else:
        frozen = base.frozen_graphs(model.config)
        export_onnx(model, directory, opset=opset,
                    graphs=tuple(g for g in GRAPH_FILES if g not in frozen))
        for graph in frozen:
            shutil.copyfile(base.graph_path(graph), directory / GRAPH_FILES[graph])
    manifest = build_manifest(model, directory, name=name, version=version, opset=opset,
                              data=data, training=training, metrics=metrics)
    write_manifest(directory, manifest)
    return directory


def load_trained_model(checkpoint: str | Path) -> tuple[SpaceMeshModel, dict[str, Any]]:
    """A model with a checkpoint's weights (CPU, eval mode) and the checkpoint's state.

    Parameters
    ----------
    checkpoint : path
        A run folder (its ``checkpoints/last.pt``) or a checkpoint file.

    Returns
    -------
    model : SpaceMeshModel
    state : dict
        See :func:`spacemesh.train.checkpoint.load_checkpoint`, plus ``base``: the
        verified :class:`BaseModel` of a connectivity-only run (see :func:`run_base`),
        or None.
    """
    from spacemesh.nn.model import model_from_config
    from spacemesh.train.checkpoint import load_checkpoint, resolve_checkpoint

    state = load_checkpoint(resolve_checkpoint(checkpoint), map_location="cpu")
    model = model_from_config(state["config"])
    state["base"] = base = run_base(state)
    if base is not None:
        model.encoder = OnnxEncoder(base.graph_path("encoder"))
    model.load_state_dict(state["model"])
    return model.eval(), state


def run_base(state: dict[str, Any]) -> BaseModel | None:
    """The base model of a connectivity-only run's checkpoint state (None for a full run),
    checked against the files the run was trained on.

    Raises
    ------
    ValueError
        The base's files changed since training.
    """
    card = state["extra"].get("base")
    if card is None:
        return None
    base = BaseModel.load(card["path"])
    now = {f: e["sha256"] for f, e in base.manifest["files"].items()}
    for graph in (GRAPH_FILES[g] for g in base.frozen_graphs(state["config"])):
        if now.get(graph) != card["files"].get(graph):
            raise ValueError(f"the base model {base.path} changed since training ({graph})")
    return base


def heldout_metrics(
    model: SpaceMeshModel | None,
    version_dir: Path,
    data: str | Path,
    *,
    connectivity_shapes: int = 100,
    pipeline_shapes: int = 16,
    steps: int | None = None,
    threads: int = 0,
) -> dict[str, Any]:
    """Measure a model on a held-out dataset (all its splits).

    Connectivity metrics use the torch model on ground-truth vertices (or, without one,
    the repository's own graphs); pipeline metrics use the onnxruntime model repository
    in ``version_dir``, and both use its manifest's decode.

    Parameters
    ----------
    model : SpaceMeshModel, optional
    version_dir : Path
    data : path
        A dataset folder (e.g. synthesised with another seed than the training set).
    connectivity_shapes, pipeline_shapes : int
        How many shapes each measurement uses.
    steps : int, optional
        Sampler steps (default: the model's).
    threads : int
        onnxruntime intra-op threads.

    Returns
    -------
    dict
    """
    from spacemesh.data.shards import first_records
    from spacemesh.runtime.pipeline import MeshGenerator
    from spacemesh.train.evaluate import connectivity_metrics, pipeline_metrics
    from spacemesh.train.loop import load_samples

    generator = MeshGenerator.from_repository(version_dir, threads=threads)
    max_vertices = generator.spec.max_vertices
    samples = load_samples(data, None, max_vertices, limit=connectivity_shapes)
    if model is None:
        conn = connectivity_metrics(generator, samples)
    else:
        section = generator.repository.manifest.get("decode", {})
        options = replace(model.decode_options, **decode_changes(section))
        conn = connectivity_metrics(model, samples, options=options)
    records = first_records(data, max_vertices=max_vertices, limit=pipeline_shapes)
    pipe = pipeline_metrics(generator, records, steps=steps)
    return {
        "dataset": Path(data).name,
        "connectivity_on_gt_vertices": conn,
        "pipeline": {**pipe, "sampler": generator.spec.method,
                     "steps": steps or generator.spec.steps},
    }


#: Vertex spacings tried by :func:`calibrate_vertex_spacing` ([-1, 1] frame).
SPACING_GRID = (1e-4, 0.025, 0.05, 0.075, 0.1, 0.125, 0.15, 0.2, 0.25, 0.3)


def require_calibration_shapes(data: str | Path, found: int | None = None,
                               max_vertices: int | None = None) -> None:
    """Refuse a calibration dataset whose ``val`` split has no shape to calibrate on.

    Parameters
    ----------
    data : path
        The dataset folder.
    found : int, optional
        Shapes of the split that fit the model (default: count the split).
    max_vertices : int, optional
        The model's vertex tokens, for the message when ``found`` is given.

    Raises
    ------
    ValueError
        One sentence naming the dataset.
    """
    from spacemesh.data.shards import open_dataset

    if found is None and len(open_dataset(data, "val")) == 0:
        raise ValueError(f"{data}: the val split has no shapes to calibrate on; use a "
                         "dataset with a val split")
    if found == 0:
        raise ValueError(f"{data}: no shape of the val split has at most {max_vertices} "
                         "vertices (the model's limit) to calibrate on")


def calibrate_vertex_spacing(
    version_dir: str | Path, data: str | Path, *, shapes: int = 48, threads: int = 0,
    grid: tuple[float, ...] = SPACING_GRID, progress: bool = False,
) -> dict[str, Any]:
    """Choose the model's ``vertex_spacing`` on a dataset's ``val`` split.

    Runs the full onnxruntime pipeline (the model's default sampler) on ``shapes``
    shapes for each spacing and keeps the one with the lowest mean Chamfer distance;
    empty outputs count with the largest Chamfer distance seen, so a spacing cannot win
    by emptying hard shapes.

    Parameters
    ----------
    version_dir : path
        The model repository version folder (its manifest is read, not changed).
    data : path
        A dataset folder; its ``val`` split is used (never the held-out set).
    shapes : int
    threads : int
        onnxruntime intra-op threads.
    grid : tuple of float
    progress : bool
        A progress bar over the grid.

    Returns
    -------
    dict
        ``vertex_spacing`` (the choice) and ``grid``, ``chamfer_mean``, ``empty``
        (one entry per spacing), ``calibration`` (a sentence).
    """
    from tqdm.auto import tqdm

    from spacemesh.data.shards import first_records
    from spacemesh.runtime.pipeline import MeshGenerator
    from spacemesh.train.evaluate import pipeline_metrics

    generator = MeshGenerator.from_repository(version_dir, threads=threads)
    spec = generator.spec
    records = first_records(data, "val", max_vertices=spec.max_vertices, limit=shapes)
    require_calibration_shapes(data, len(records), spec.max_vertices)
    rows = []
    for spacing in tqdm(grid, desc="vertex spacing", disable=not progress):
        generator.spec = replace(spec, vertex_spacing=float(spacing))
        rows.append(pipeline_metrics(generator, records))
    worst = max((r["chamfer_mean"] for r in rows if np.isfinite(r["chamfer_mean"])),
                default=float("inf"))

    def score(row: dict[str, float]) -> float:
        mean = row["chamfer_mean"] if np.isfinite(row["chamfer_mean"]) else worst
        return (1 - row["empty"]) * mean + row["empty"] * worst

    best = int(np.argmin([score(r) for r in rows]))
    return {
        "vertex_spacing": float(grid[best]),
        "grid": [float(s) for s in grid],
        "chamfer_mean": [round(float(r["chamfer_mean"]), 5) for r in rows],
        "empty": [round(float(r["empty"]), 4) for r in rows],
        "calibration": f"min mean pipeline Chamfer on {len(records)} shapes of the val "
                       f"split of {Path(data).name}",
    }


def record_vertex_spacing(
    version_dir: str | Path, data: str | Path, training: dict[str, Any], *, threads: int = 0
) -> dict[str, Any]:
    """Choose the vertex spacing (:func:`calibrate_vertex_spacing`) and write it into the
    manifest: the sampler's ``vertex_spacing`` and, with how it was found, ``training``.

    Parameters
    ----------
    version_dir : path
    data : path
        A dataset folder (its ``val`` split is used).
    training : dict
        The manifest's ``training`` section to extend.
    threads : int

    Returns
    -------
    dict
        The new manifest.
    """
    spacing = calibrate_vertex_spacing(version_dir, data, threads=threads)
    sampler = json.loads((Path(version_dir) / MANIFEST).read_text())["sampler"]
    return update_manifest(version_dir, training={**training, "vertex_spacing": spacing},
                           sampler={**sampler, "vertex_spacing": spacing["vertex_spacing"]})


def export_run(
    run: str | Path,
    root: str | Path,
    *,
    name: str | None = None,
    version: int = 1,
    eval_data: str | Path | None = None,
    calibrate_data: str | Path | None = None,
    connectivity_shapes: int = 100,
    pipeline_shapes: int = 16,
    threads: int = 0,
) -> Path:
    """Export a training run's newest checkpoint as a model repository.

    Parameters
    ----------
    run : path
        Run folder or checkpoint file.
    root : path
        Repository root; the model goes to ``ROOT/NAME/VERSION``.
    name : str, optional
        Default ``spacemesh-<config name>``.
    version : int
    eval_data : path, optional
        Held-out dataset to measure (metrics go into the manifest); without it the
        manifest records the run's last validation metrics.
    calibrate_data : path, optional
        Dataset whose ``val`` split recalibrates the edge threshold ``tau`` (see
        :func:`spacemesh.train.evaluate.calibrate_threshold`, then
        :func:`~spacemesh.train.evaluate.calibrate_decode_threshold`) and then chooses the
        sampler's ``vertex_spacing`` (:func:`calibrate_vertex_spacing`); the values and
        how they were found go into the manifest's ``training`` section.
    connectivity_shapes, pipeline_shapes : int
    threads : int
        onnxruntime threads for the measurement.

    Returns
    -------
    Path
        The version folder.

    Raises
    ------
    ValueError
        ``calibrate_data`` has no val shape that fits the model
        (:func:`require_calibration_shapes`).
    """

    if calibrate_data is not None:
        require_calibration_shapes(calibrate_data)
    model, state = load_trained_model(run)
    base = state["base"]
    extra = state["extra"]
    config = state["config"]
    name = name or f"spacemesh-{config.name}"
    training = {
        "steps": state["step"],
        "connectivity_steps": state["step"] * config.train.connectivity_steps,
        "seconds": round(float(extra.get("train_seconds", 0.0)), 1),
        "device": extra.get("device", "cpu"),
        "world_size": extra.get("world_size", 1),
        "batch_size": config.train.batch_size,
        "optimizer": f"Adam(lr={config.train.lr})",
        "parameters": sum(p.numel() for p in model.parameters()),
    }
    if config.train.diffusion_only:
        training["connectivity_steps"] = 0
        training["shapes"] = state["step"] * config.train.batch_size * training["world_size"]
        training["parameters"] = sum(p.numel() for p in model.denoiser.parameters())
        training["trained"] = ("denoiser only, on a frozen encoder (volumes cached for "
                               f"{config.train.encoder_cache} augmentations per shape)")
    elif base is not None:
        training["steps"] = 0
        training["parameters"] = sum(p.numel() for p in model.connectivity.parameters())
        training["trained"] = "connectivity network only, on the base's frozen encoder"
    if base is not None:
        training["base"] = {k: extra["base"][k] for k in ("name", "version", "files")}
        training["base_training"] = extra["base"].get("training", {})
    decode = decode_section(extra.get("data", {}))
    if calibrate_data is not None:
        from spacemesh.train.evaluate import (
            DECODE_PAIR_RATIOS,
            calibrate_decode_threshold,
            calibrate_threshold,
            predicted_embeddings,
        )
        from spacemesh.train.loop import load_samples

        samples = load_samples(calibrate_data, "val", config.max_vertices,
                               limit=connectivity_shapes)
        require_calibration_shapes(calibrate_data, len(samples), config.max_vertices)
        learned = float(model.connectivity.tau.detach())
        embeddings = predicted_embeddings(model, samples)  # at the learned tau
        options = replace(model.decode_options, **decode_changes(decode))
        f1_tau, f1 = calibrate_threshold(samples, embeddings, options)
        tau, decoded = calibrate_decode_threshold(samples, embeddings, options, f1_tau)
        with torch.no_grad():
            model.connectivity.tau.fill_(tau)
        training["tau"] = {
            "learned": learned, "edge_f1_best": f1_tau, "val_edge_f1": f1, "calibrated": tau,
            "val_decoded": decoded,
            "calibration": f"max mean edge F1 on {len(samples)} shapes of the val split of "
                           f"{Path(calibrate_data).name}, then the threshold passing "
                           f"{decoded['ratio']:g}x as many pairs, of "
                           f"{', '.join(f'{r:g}' for r in DECODE_PAIR_RATIOS)}x, for the "
                           "max mean decoded next accuracy",
        }
    metrics = {"validation": extra.get("validation", {})}
    data = dict(extra.get("data", {}))
    if "base" in data:  # what the base was trained on, without this machine's path
        data["base"] = {k: v for k, v in data["base"].items() if k != "path"}
    directory = write_model_repository(model, root, name=name, version=version, data=data,
                                       training=training, metrics=metrics, base=base)
    update_manifest(directory, decode=decode)
    record_golden(directory)
    if calibrate_data is not None:
        record_vertex_spacing(directory, calibrate_data, training, threads=threads)
    if eval_data is not None:
        metrics["heldout"] = heldout_metrics(
            model, directory, eval_data, connectivity_shapes=connectivity_shapes,
            pipeline_shapes=pipeline_shapes, threads=threads,
        )
        update_manifest(directory, metrics=metrics)
    return directory


def repackage_repository(
    source: str | Path,
    root: str | Path,
    *,
    version: int,
    name: str | None = None,
    eval_data: str | Path | None = None,
    calibrate_data: str | Path | None = None,
    connectivity_shapes: int = 100,
    pipeline_shapes: int = 16,
    threads: int = 0,
) -> Path:
    """A new version of an exported model with today's decode, no torch run needed.

    The graphs are copied byte for byte (their sha256 checked against the source
    manifest), the manifest keeps everything but its ``version``, gets the ``decode``
    section :func:`decode_section` writes for its data card now, records where it came
    from (``derived_from``: name, version, the old decode section), and is measured
    again: ``calibrate_data`` chooses the vertex spacing anew
    (:func:`calibrate_vertex_spacing`; ``tau`` lives in the connectivity graph and
    stays), ``eval_data`` replaces the held-out metrics (:func:`heldout_metrics` on the
    repository's own graphs).

    Parameters
    ----------
    source : path
        A version folder (``ROOT/NAME/VERSION`` with its ``manifest.json``).
    root : path
        Repository root; the model goes to ``ROOT/NAME/VERSION``.
    version : int
        The new version (its folder must not be the source).
    name : str, optional
        Default: the source's.
    eval_data, calibrate_data : path, optional
    connectivity_shapes, pipeline_shapes, threads : int
        As in :func:`export_run`.

    Returns
    -------
    Path
        The new version folder.

    Raises
    ------
    ValueError
        The source is not a model version folder, a graph's checksum does not match,
        the target is the source, or ``calibrate_data`` has no val shape.
    """

    source = Path(source)
    if not (source / MANIFEST).is_file():
        raise ValueError(f"{source}: not a model version folder (no {MANIFEST})")
    if calibrate_data is not None:
        require_calibration_shapes(calibrate_data)
    manifest = verified_manifest(source)
    name = name or str(manifest["name"])
    directory = Path(root) / name / str(version)
    if directory.resolve() == source.resolve():
        raise ValueError(f"{directory} is the source; choose another --version")
    directory.mkdir(parents=True, exist_ok=True)
    for file in manifest["files"]:
        shutil.copyfile(source / file, directory / file)
    manifest["derived_from"] = {"name": manifest["name"], "version": manifest["version"],
                                "decode": manifest.get("decode", {}),
                                "what": "the same graphs, byte for byte, with the decode "
                                        "of this release"}
    manifest.update(name=name, version=version, decode=decode_section(manifest["data"]),
                    geometry=geometry_section())
    manifest["sampler"].update(POINTS_START, retry_seeds=RELEASE_RETRY_SEEDS)
    write_manifest(directory, manifest)
    if SECTION_GOLDEN not in manifest:  # exported before the section existed
        manifest = record_golden(directory)
    if calibrate_data is not None:
        manifest = record_vertex_spacing(directory, calibrate_data,
                                         manifest.get("training", {}), threads=threads)
    if eval_data is not None:
        metrics = {**manifest.get("metrics", {}), "heldout": heldout_metrics(
            None, directory, eval_data, connectivity_shapes=connectivity_shapes,
            pipeline_shapes=pipeline_shapes, threads=threads,
        )}
        update_manifest(directory, metrics=metrics)
    return directory
