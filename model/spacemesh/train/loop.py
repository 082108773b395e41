"""The training loop: Adam over all three networks, the paper's 10:1 step schedule.

One *diffusion step* trains the encoder and denoiser on a batch of shapes padded to
``max_vertices`` tokens; it is followed by ``connectivity_steps`` *connectivity steps*
that train the connectivity network (and, if configured, the encoder) on ground-truth
vertices: other batches, of shapes of similar size, padded to their own largest shape.
Steps are counted in diffusion steps.

With a *base* (``TrainOptions.base``, a model repository), only the connectivity network
trains: on the base's frozen encoder, run in onnxruntime
(:class:`spacemesh.nn.base_model.OnnxEncoder`); a step is then ``connectivity_steps``
connectivity steps and no diffusion step, and export keeps the base's encoder and
denoiser graphs.

A *diffusion-only* run (``TrainConfig.diffusion_only``) trains the denoiser alone, on a
frozen encoder: a base's (in onnxruntime; export then keeps the base's encoder and
connectivity graphs) or an ``--init-from`` run's. No connectivity step is taken, and the
encoder's volumes of each augmented shape are computed once and cached
(:mod:`spacemesh.train.encoder_cache`).

A run stops cleanly at any time: SIGINT or SIGTERM (Ctrl-C, ``kill``, a scheduler's
time limit) finishes the current step and writes a checkpoint, as ``--max-minutes`` does;
``TrainConfig.checkpoint_minutes`` bounds what a hard kill loses. ``--resume`` continues
with the same random streams, so a resumed run draws the batches an uninterrupted one
would.

A run folder holds::

    RUN/config.json              the ModelConfig
    RUN/data.json                the data card (dataset manifest summary)
    RUN/metrics.csv              one row per log / validation
    RUN/curves.png               curves drawn from metrics.csv
    RUN/checkpoints/last.pt      newest checkpoint (``--resume`` continues from it)
    RUN/checkpoints/step-N.pt    periodic checkpoints
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import signal
import threading
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from spacemesh.data.augment import get_augment
from spacemesh.data.shards import MANIFEST, open_dataset
from spacemesh.nn.base_model import BaseModel, OnnxEncoder
from spacemesh.nn.config import ModelConfig, TrainConfig
from spacemesh.nn.model import SpaceMeshModel, model_from_config
from spacemesh.train.batching import Sample, collate, prepare_sample
from spacemesh.train.checkpoint import (
    LAST,
    checkpoint_dir,
    latest_checkpoint,
    load_checkpoint,
    resolve_checkpoint,
    restore_rng,
    save_checkpoint,
)
from spacemesh.train.distributed import (
    DistInfo,
    any_rank,
    barrier,
    cleanup,
    setup_distributed,
    wrap_model,
)
from spacemesh.train.encoder_cache import EncoderCache
from spacemesh.train.evaluate import connectivity_metrics
from spacemesh.train.logging import MetricsLog, plot_curves


def learning_rate(train: TrainConfig, step: int) -> float:
    """A linear warm-up, then a half cosine from ``lr`` to ``lr * final_lr_ratio``.

    Parameters
    ----------
    train : TrainConfig
    step : int
        Diffusion step, from 0.

    Returns
    -------
    float
    """
    warm = min(1.0, (step + 1) / max(train.warmup, 1))
    progress = min(1.0, step / max(train.steps, 1))
    ratio = train.final_lr_ratio
    return train.lr * warm * (ratio + (1.0 - ratio) * 0.5 * (1.0 + math.cos(math.pi * progress)))


@dataclass
class TrainOptions:
    """What to train, on what, and where to write it.

    Attributes
    ----------
    config : ModelConfig
    data : Path
        Dataset folder (its ``train`` split is used).
    out : Path
        Run folder.
    resume : bool
        Continue from ``out/checkpoints/last.pt``.
    steps : int, optional
        Override ``config.train.steps``.
    val_data : Path, optional
        Held-out dataset for validation (default: the ``val`` split of ``data``).
    device : str, optional
        ``cpu`` or ``cuda`` (default CUDA when available).
    threads : int, optional
        Torch CPU threads.
    seed : int
    max_seconds : float, optional
        Stop (with a checkpoint) once this much wall time has passed in this session.
    progress : bool
        Show a progress bar.
    base : Path, optional
        A model repository: train only a new connectivity network (``config``'s) on its
        frozen encoder; the encoder, denoiser, diffusion and vertex count are the base's.
    mix : tuple of Path
        More datasets whose ``train`` splits join ``data``'s (a mix of generator styles;
        validation stays on ``data``'s ``val`` split or ``val_data``).
    init_from : Path, optional
        A run folder, checkpoint or exported connectivity-only model version folder
        (:func:`spacemesh.train.onnx_import.init_from_repository`) to start from
        (fine-tuning): its weights, with a new
        optimiser and the learning-rate schedule from step 0. Its networks must be the
        config's; a connectivity-only run's base is inherited (and ``base``, if given,
        must be the same model). Ignored when ``resume`` finds a checkpoint.
    """

    config: ModelConfig
    data: Path
    out: Path
    resume: bool = False
    steps: int | None = None
    val_data: Path | None = None
    device: str | None = None
    threads: int | None = None
    seed: int = 0
    max_seconds: float | None = None
    progress: bool = True
    base: Path | None = None
    init_from: Path | None = None
    mix: tuple[Path, ...] = ()


@dataclass
class TrainSummary:
    """The outcome of :func:`train`."""

    run: Path
    steps: int
    seconds: float
    checkpoint: Path | None
    metrics: dict[str, float] = field(default_factory=dict)


def _init_base(init: dict[str, Any], base_path: Path | None) -> Path | None:
    """The base of a fine-tuning run: ``base_path`` if given, else the init run's (None
    for a full run, which cannot start a connectivity-only run)."""
    stored = init["extra"].get("base")
    if stored is None:
        if base_path is not None:
            raise ValueError(f"--init-from {init['path']} is a full run; it has no "
                             "connectivity-only weights for --base")
        return None
    return base_path if base_path is not None else Path(stored["path"])


def _check_init(init: dict[str, Any], config: ModelConfig, given_base: BaseModel | None
                ) -> None:
    """Refuse an init checkpoint whose networks differ from the config's, or that was
    trained on other base files than ``given_base`` (a ``--base`` given with it). A
    diffusion-only run may bring its own denoiser (it starts fresh, see
    :func:`_load_init`)."""
    stored = init["extra"].get("base")
    if given_base is not None and given_base.card()["files"] != stored["files"]:
        raise ValueError(f"--init-from {init['path']} was trained on the base "
                         f"{stored['path']}, not on {given_base.path}")
    have, want = init["config"].to_dict(), config.to_dict()
    free = ("name", "train", "denoiser") if config.train.diffusion_only else ("name", "train")
    differ = [k for k in want if k not in free and have.get(k) != want[k]]
    if differ:
        raise ValueError(f"--init-from {init['path']}: its {', '.join(differ)} differ from "
                         f"the {config.name} config's")


def _load_init(model: SpaceMeshModel, init: dict[str, Any]) -> None:
    """Load an init checkpoint's weights; a denoiser of another architecture (a
    diffusion-only run's new denoiser) keeps its fresh weights."""
    if "connectivity" in init:  # an exported model: its connectivity network
        model.connectivity.load_state_dict(init["connectivity"])
        return
    weights = init["model"]
    if init["config"].denoiser != model.config.denoiser:
        weights = {k: v for k, v in weights.items() if not k.startswith("denoiser.")}
    missing, unexpected = model.load_state_dict(weights, strict=False)
    wrong = [k for k in missing if not k.startswith("denoiser.")] + list(unexpected)
    if wrong:
        raise ValueError(f"--init-from {init['path']}: weights do not fit: {', '.join(wrong)}")


def _check_resumed_base(state: dict[str, Any], base: BaseModel | None) -> None:
    """Refuse to resume on another base than the run's (the same files, wherever they
    are now: ``--base`` may name the base's new place, e.g. on another machine)."""
    stored = state["extra"].get("base")
    if (stored is None) != (base is None):
        raise ValueError("--resume: the run was trained " + (
            "without a base model" if stored is None else f"on the base {stored['path']}"))
    if base is not None and base.card()["files"] != stored["files"]:
        raise ValueError(f"--resume: {base.path} is not the base the run was trained on "
                         f"({stored['path']}): its files differ")


def _base_volumes(model: SpaceMeshModel) -> list[torch.Tensor]:
    """The frozen encoder's volumes of a fixed random cloud, as graph-parity inputs."""
    channels = 6 if model.config.encoder.normals else 3
    points = torch.rand(1, model.config.encoder.n_points, channels,
                        generator=torch.Generator().manual_seed(0)) * 2 - 1
    with torch.no_grad():
        return [v.cpu() for v in model.encoder(points)]


def _base_denoiser(model: SpaceMeshModel, base: BaseModel, volumes: list[torch.Tensor]
                   ) -> None:
    """Start a diffusion-only run's denoiser from the base's (``warm_start``): its graph is
    read back into a volumes-only twin, checked against onnxruntime on ``volumes``
    (:func:`_base_volumes`), and grafted."""
    from dataclasses import replace

    from spacemesh.nn.denoiser import graft_denoiser
    from spacemesh.nn.model import model_from_config
    from spacemesh.train.onnx_import import load_denoiser

    twin_config = replace(model.config, denoiser=replace(model.config.denoiser, local_points=0))
    twin = model_from_config(twin_config).denoiser
    load_denoiser(base.graph_path("denoiser"), twin, volumes)
    device = next(model.denoiser.parameters()).device
    graft_denoiser(twin, model.denoiser.cpu())
    model.denoiser.to(device)


def _base_connectivity(model: SpaceMeshModel, base: BaseModel, volumes: list[torch.Tensor]
                       ) -> None:
    """Read the base's connectivity weights into a diffusion-only run's (frozen) network,
    so that the run's torch model is the whole model its export will be (checked on
    ``volumes``, :func:`_base_volumes`)."""
    from spacemesh.train.onnx_import import load_connectivity

    device = next(model.connectivity.parameters()).device
    load_connectivity(base.graph_path("connectivity"), model.connectivity.cpu(), volumes)
    model.connectivity.to(device)


def _init_card(init: dict[str, Any]) -> dict[str, Any]:
    """What a fine-tuning run records about its start: the checkpoint's step, training
    time and data card."""
    extra = init["extra"]
    data = {k: v for k, v in extra.get("data", {}).items() if k != "base"}
    return {"checkpoint": str(init["path"]), "step": int(init["step"]),
            "train_seconds": float(extra.get("train_seconds", 0.0)), "data": data}


def data_card(directory: str | Path, max_vertices: int, n_train: int, n_val: int) -> dict:
    """What a model was trained on: the dataset manifest's header and counts.

    Parameters
    ----------
    directory : path
    max_vertices : int
        Shapes with more vertices were skipped.
    n_train, n_val : int
        Shapes used.

    Returns
    -------
    dict
    """
    path = Path(directory) / MANIFEST
    manifest = json.loads(path.read_text())
    keep = ("source", "generator_version", "seed", "style", "vertex_range", "points",
            "count_requested", "counts", "splits")
    card = {k: manifest[k] for k in keep if k in manifest}
    card.update(
        dataset=Path(directory).name,
        manifest_sha256=hashlib.sha256(path.read_bytes()).hexdigest(),
        max_vertices=max_vertices,
        train_shapes_used=n_train,
        val_shapes_used=n_val,
    )
    return card


def load_samples(
    directory: str | Path, split: str | None, max_vertices: int, limit: int | None = None,
    log: Callable[[str], None] | None = None,
) -> list[Sample]:
    """Prepared shapes of one split with at most ``max_vertices`` vertices.

    Parameters
    ----------
    directory : path
    split : str or None
    max_vertices : int
    limit : int, optional
        Stop after this many.
    log : callable, optional

    Returns
    -------
    list of Sample
    """
    dataset = open_dataset(directory, split=split, cache_shards=2)
    samples: list[Sample] = []
    skipped = 0
    for record in dataset:
        if record.mesh.n_vertices > max_vertices:
            skipped += 1
            continue
        samples.append(prepare_sample(record))
        if limit is not None and len(samples) >= limit:
            break
    if log is not None:
        log(f"{directory} [{split}]: {len(samples)} shapes, {skipped} skipped (> {max_vertices} "
            "vertices)")
    return samples


class StopRequests:
    """SIGINT and SIGTERM ask the loop to stop after the current step, with a checkpoint
    (a second signal interrupts at once). Handlers are installed only in the main
    thread and restored on exit."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopRequests:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum: int, _frame: Any) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum

    def __exit__(self, *_exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    @property
    def requested(self) -> bool:
        """A stop was asked for."""
        return self.signal is not None


def _autocast(device: torch.device):
    if device.type == "cuda":
        return torch.autocast("cuda", dtype=torch.bfloat16)
    return contextlib.nullcontext()


class Trainer:
    """State of one training process (see :func:`train`)."""

    def __init__(self, options: TrainOptions, info: DistInfo, log: Callable[[str], None]):
        self.options = options
        self.info = info
        self.log = log
        config = options.config
        if options.steps is not None:
            config = config.with_train(steps=options.steps)
        self.out = Path(options.out)
        self.start_step = 0
        self.elapsed_before = 0.0
        state = None
        base_path = options.base
        if options.resume:
            last = latest_checkpoint(self.out)
            if last is None:
                log(f"no checkpoint in {self.out}; starting from scratch")
            else:
                state = load_checkpoint(last, map_location="cpu")
                # the stored architecture wins; the step budget and the decay come from
                # the requested config (a run may be extended)
                config = state["config"].with_train(
                    steps=config.train.steps, final_lr_ratio=config.train.final_lr_ratio,
                    connectivity_jitter=config.train.connectivity_jitter,
                    checkpoint_minutes=config.train.checkpoint_minutes,
                )
                stored_base = state["extra"].get("base")
                if stored_base is not None and options.base is None:
                    base_path = Path(stored_base["path"])
        init = None
        if state is None and options.init_from is not None:
            from spacemesh.train.onnx_import import init_from_repository, is_model_version

            if is_model_version(options.init_from):
                init = init_from_repository(options.init_from)
            else:
                init_path = resolve_checkpoint(options.init_from)
                init = load_checkpoint(init_path, map_location="cpu")
                init["path"] = init_path
            base_path = _init_base(init, base_path)
        self.base = None if base_path is None else BaseModel.load(base_path)
        if state is not None:  # a run moved to another machine names its base again
            _check_resumed_base(state, self.base)
        if self.base is not None:
            if state is None:
                config = self.base.merged_config(config)
            kind = "denoiser" if config.train.diffusion_only else "connectivity"
            log(f"{kind} only, on the frozen encoder of {self.base.path}")
        if init is not None:
            _check_init(init, config, self.base if options.base is not None else None)
        self.diffusion_only = config.train.diffusion_only
        if self.diffusion_only and state is None and init is None and self.base is None:
            raise ValueError("diffusion-only training freezes a trained encoder: give a base "
                             "model (--base) or a run to start from (--init-from)")
        self.config = config
        self.augment = get_augment(config.train.augment)
        self.rng = np.random.default_rng(options.seed + 1000 * info.rank)
        self.generator = torch.Generator().manual_seed(options.seed + 1000 * info.rank)
        self.model: SpaceMeshModel = model_from_config(config).to(info.device)
        if self.base is not None:
            self.model.encoder = OnnxEncoder(self.base.graph_path("encoder"),
                                             threads=options.threads or 0)
        if self.diffusion_only:
            self.model.encoder.requires_grad_(False)
            self.model.connectivity.requires_grad_(False)
            if self.base is not None and state is None:
                volumes = _base_volumes(self.model)
                _base_connectivity(self.model, self.base, volumes)
                if config.train.warm_start:
                    _base_denoiser(self.model, self.base, volumes)
                    log(f"denoiser warm-started from {self.base.graph_path('denoiser')}")
        elif self.base is not None:
            self.model.denoiser.requires_grad_(False)
        trainable = [p for p in self.model.parameters() if p.requires_grad]
        self.optimizer = torch.optim.Adam(trainable, lr=config.train.lr)
        if state is not None:
            self.model.load_state_dict(state["model"])
            self.optimizer.load_state_dict(state["optimizer"])
            self.start_step = state["step"]
            self.elapsed_before = float(state["extra"].get("train_seconds", 0.0))
            if info.is_main:
                restore_rng(self.rng, state["numpy_rng"])
                self.generator.set_state(state["torch_rng"])
            else:  # only rank 0's streams are stored; the others start fresh ones
                self.rng = np.random.default_rng([options.seed, info.rank, self.start_step])
                self.generator.manual_seed(options.seed + 1000 * info.rank + self.start_step)
            log(f"resumed from {latest_checkpoint(self.out)} at step {self.start_step}")
        elif init is not None:
            _load_init(self.model, init)
            log(f"initialised from {init['path']} (step {init['step']})")
        self.ddp = wrap_model(self.model, info)
        mv = config.max_vertices
        self.train_samples = load_samples(options.data, "train", mv, log=log)
        mixed = [load_samples(extra, "train", mv, log=log) for extra in options.mix]
        for extra in mixed:
            self.train_samples.extend(extra)
        if not self.train_samples:
            raise ValueError(f"no training shapes with at most {mv} vertices in {options.data}")
        self.by_size = np.argsort([s.n_vertices for s in self.train_samples], kind="stable")
        val_dir = options.val_data or options.data
        val_split = None if options.val_data else "val"
        self.val_samples = load_samples(val_dir, val_split, mv, config.train.val_shapes, log=log)
        self.cache = None
        if self.diffusion_only and config.train.encoder_cache:
            enc = config.encoder
            self.cache = EncoderCache(
                self.model.encoder, self.train_samples, variants=config.train.encoder_cache,
                seed=options.seed, n_points=enc.n_points, normals=enc.normals, pad_to=mv,
                scale_range=config.train.scale_range, device=info.device,
                augment=self.augment,
            )
        self.card = data_card(options.data, mv, len(self.train_samples), len(self.val_samples))
        if options.mix:
            self.card["mix"] = [data_card(extra, mv, len(samples), 0)
                                for extra, samples in zip(options.mix, mixed, strict=True)]
        self.card["augment"] = config.train.augment
        if self.base is not None:
            self.card["base"] = self.base.card()
        if init is not None:
            self.card["init"] = _init_card(init)
        elif state is not None and "init" in state["extra"].get("data", {}):
            self.card["init"] = state["extra"]["data"]["init"]
        self.metrics = MetricsLog(self.out / "metrics.csv")
        self.last_validation: dict[str, float] = (
            dict(state["extra"].get("validation", {})) if state is not None else {}
        )
        if self.info.is_main:
            self.metrics.truncate(self.start_step)
            self.out.mkdir(parents=True, exist_ok=True)
            (self.out / "config.json").write_text(json.dumps(config.to_dict(), indent=2))
            (self.out / "data.json").write_text(json.dumps(self.card, indent=2))

    def lr_at(self, step: int) -> float:
        """Learning rate at ``step`` (see :func:`learning_rate`)."""
        return learning_rate(self.config.train, step)

    def _pick(self, diffusion: bool) -> np.ndarray:
        """Indices of one batch; connectivity batches take shapes of similar size (a random
        window of the size order), so that little of each batch is padding."""
        size = self.config.train.batch_size
        total = len(self.train_samples)
        if diffusion or total <= 4 * size:
            return self.rng.choice(total, size, replace=total < size)
        window = 4 * size
        start = self.rng.integers(0, total - window + 1)
        return self.by_size[start + self.rng.choice(window, size, replace=False)]

    def _batch(self, diffusion: bool):
        train = self.config.train
        samples = [self.train_samples[i] for i in self._pick(diffusion)]
        enc = self.config.encoder
        batch = collate(
            samples, n_points=enc.n_points, normals=enc.normals,
            pad_to=self.config.max_vertices if diffusion else None,
            connectivity=not diffusion, rng=self.rng, scale_range=train.scale_range,
            jitter=0.0 if diffusion else train.connectivity_jitter, augment=self.augment,
        )
        return batch.to(self.info.device)

    def _frozen_batch(self):
        """A diffusion batch and its frozen encoder's volumes (cached, or computed
        without gradients)."""
        if self.cache is not None:
            return self.cache.batch(self._pick(True), self.rng)
        batch = self._batch(True)
        with torch.no_grad():
            volumes = [v.detach() for v in self.model.encoder(batch.points)]
        return batch, volumes

    def _step(self, mode: str) -> dict[str, float]:
        volumes = None
        if mode == "diffusion" and self.diffusion_only:
            batch, volumes = self._frozen_batch()
        else:
            batch = self._batch(mode == "diffusion")
        self.optimizer.zero_grad(set_to_none=True)
        with _autocast(self.info.device):
            out = self.ddp(mode, batch.points, batch.positions, batch.valid, batch.adjacency,
                           batch.table, self.generator, volumes)
        out["loss"].backward()
        clip = self.config.train.grad_clip
        if clip > 0:
            torch.nn.utils.clip_grad_norm_(
                [p for p in self.model.parameters() if p.requires_grad], clip)
        self.optimizer.step()
        return {k: float(v.detach()) for k, v in out.items()}

    @torch.no_grad()
    def validate(self) -> dict[str, float]:
        """Held-out diffusion loss and connectivity metrics (on rank 0's model); with an
        augmentation, also the diffusion loss on augmented clouds (``val_epsilon_augmented``,
        the same shapes, timesteps and noise)."""
        model = self.model.eval()
        enc = self.config.encoder
        rng = np.random.default_rng(1234)
        gen = torch.Generator().manual_seed(1234)
        augment_rng = np.random.default_rng(4321)  # own streams: val_epsilon stays
        augment_gen = torch.Generator().manual_seed(1234)  # comparable across runs
        sums: dict[str, list[float]] = defaultdict(list)
        bs = self.config.train.batch_size
        for start in range(0, len(self.val_samples), bs):
            chunk = self.val_samples[start : start + bs]
            if self.base is None or self.diffusion_only:
                b = collate(chunk, n_points=enc.n_points, normals=enc.normals,
                            pad_to=self.config.max_vertices, connectivity=False, rng=rng)
                b = b.to(self.info.device)
                out = model("diffusion", b.points, b.positions, b.valid, generator=gen)
                sums["val_epsilon"].append(float(out["epsilon"]))
                sums["val_mask"].append(float(out["mask"]))
                if not self.augment.is_identity:  # also on the run's realistic clouds
                    b = collate(chunk, n_points=enc.n_points, normals=enc.normals,
                                pad_to=self.config.max_vertices, connectivity=False,
                                rng=augment_rng, augment=self.augment).to(self.info.device)
                    out = model("diffusion", b.points, b.positions, b.valid,
                                generator=augment_gen)
                    sums["val_epsilon_augmented"].append(float(out["epsilon"]))
            if self.diffusion_only:
                continue
            b = collate(chunk, n_points=enc.n_points, normals=enc.normals, rng=rng)
            b = b.to(self.info.device)
            out = model("connectivity", b.points, b.positions, b.valid, b.adjacency, b.table)
            sums["val_edge"].append(float(out["edge"]))
            sums["val_permutation"].append(float(out["permutation"]))
        row = {k: float(np.mean(v)) for k, v in sums.items()}
        if not self.diffusion_only:
            conn = connectivity_metrics(model, self.val_samples, batch_size=bs)
            row.update(val_edge_f1=conn["edge_f1"], val_next_accuracy=conn["next_accuracy"],
                       val_exact=conn["exact"])
        model.train()
        return row

    def save(self, step: int, seconds: float) -> Path:
        """Write ``last.pt`` (and ``step-N.pt``); returns the last path."""
        folder = checkpoint_dir(self.out)
        validation = {k.removeprefix("val_"): v for k, v in self.last_validation.items()}
        extra = {"train_seconds": seconds, "data": self.card, "world_size": self.info.world_size,
                 "device": str(self.info.device), "validation": validation}
        if self.base is not None:
            extra["base"] = self.base.card()
        path = save_checkpoint(folder / LAST, model=self.model, optimizer=self.optimizer,
                               step=step, config=self.config, rng=self.rng,
                               torch_generator=self.generator, extra=extra)
        save_checkpoint(folder / f"step-{step:07d}.pt", model=self.model, optimizer=None,
                        step=step, config=self.config, extra=extra)
        return path

    def run(self) -> TrainSummary:
        """Train until ``config.train.steps``, ``max_seconds`` or a stop signal."""
        with StopRequests() as stops:
            return self._run(stops)

    def train_step(self, step: int, running: dict[str, list[float]]) -> None:
        """One step at the learning rate of ``step``: a diffusion step (unless the run
        trains connectivity only), then the connectivity steps (unless diffusion only);
        losses are appended to ``running``."""
        for group in self.optimizer.param_groups:
            group["lr"] = self.lr_at(step)
        if self.base is None or self.diffusion_only:
            for k, v in self._step("diffusion").items():
                running[f"train_{k}" if k != "loss" else "train_diffusion_loss"].append(v)
        for _ in range(0 if self.diffusion_only else self.config.train.connectivity_steps):
            for k, v in self._step("connectivity").items():
                running[f"train_{k}" if k != "loss" else "train_connectivity_loss"].append(v)

    def _shapes(self, step: int) -> int:
        """Shapes the denoiser has seen after ``step`` steps (0 if it does not train)."""
        if self.base is not None and not self.diffusion_only:
            return 0
        return step * self.config.train.batch_size * self.info.world_size

    def _run(self, stops: StopRequests) -> TrainSummary:
        from tqdm import tqdm

        train = self.config.train
        start = time.perf_counter()
        last_save = start
        running: dict[str, list[float]] = defaultdict(list)
        bar = tqdm(total=train.steps, initial=self.start_step, unit="step",
                   disable=not (self.options.progress and self.info.is_main), dynamic_ncols=True)
        step = self.start_step
        last_path = latest_checkpoint(self.out)
        last_row: dict[str, float] = {}
        self.model.train()
        while step < train.steps:
            self.train_step(step, running)
            step += 1
            now = time.perf_counter()
            seconds = self.elapsed_before + now - start
            bar.update(1)
            bar.set_postfix({short: f"{np.mean(running[key][-20:]):.4f}"
                             for short, key in (("edge", "train_edge"),
                                                ("perm", "train_permutation"),
                                                ("eps", "train_epsilon")) if running.get(key)})
            out_of_time = self.options.max_seconds is not None and (
                now - start > self.options.max_seconds
            )
            stop = any_rank(out_of_time or stops.requested, self.info) or step >= train.steps
            due = any_rank(train.checkpoint_minutes > 0
                           and now - last_save > 60.0 * train.checkpoint_minutes, self.info)
            if step % train.val_every == 0 or step % train.checkpoint_every == 0 or stop or due:
                if self.info.is_main:
                    row = {"step": step, "seconds": seconds, "lr": self.lr_at(step),
                           "shapes": self._shapes(step)}
                    row.update({k: float(np.mean(v)) for k, v in running.items()})
                    running.clear()
                    if step % train.val_every == 0 or stop:
                        self.last_validation = {"step": step, **self.validate()}
                        row.update(self.last_validation)
                        self.log(f"step {step}: " + ", ".join(
                            f"{name} {row[key]:.4f}" for name, key in (
                                ("val edge F1", "val_edge_f1"), ("next", "val_next_accuracy"),
                                ("eps", "val_epsilon")) if key in row))
                    self.metrics.append(row)
                    plot_curves(self.metrics, self.out / "curves.png")
                    last_row = row
                    if step % train.checkpoint_every == 0 or stop or due:
                        last_path = self.save(step, seconds)
                        last_save = time.perf_counter()
                barrier(self.info)
            if stop:
                break
        bar.close()
        if stops.requested:
            self.log(f"stopped by signal {stops.signal} at step {step}; checkpoint {last_path}")
        seconds = self.elapsed_before + time.perf_counter() - start
        return TrainSummary(self.out, step, seconds, last_path, last_row)


def train(options: TrainOptions, log: Callable[[str], None] = print) -> TrainSummary:
    """Train a model (single process, or one rank of a ``torchrun`` job).

    Parameters
    ----------
    options : TrainOptions
    log : callable
        Receives progress messages (rank 0 only).

    Returns
    -------
    TrainSummary
    """
    if options.threads:
        torch.set_num_threads(options.threads)
    info = setup_distributed(options.device)
    torch.manual_seed(options.seed + info.rank)

    def main_log(message: str) -> None:
        if info.is_main:
            log(message)

    try:
        summary = Trainer(options, info, main_log).run()
    finally:
        cleanup(info)
    if not math.isfinite(summary.metrics.get("train_connectivity_loss", 0.0)):
        main_log("warning: the connectivity loss is not finite")
    return summary
