"""Parallel, resumable, deterministic generation of a synthetic dataset.

Shape ``i`` of a run draws everything (vertex target, solid, tessellation,
conditioning points) from ``numpy.random.default_rng([seed, i])``; a rejected
attempt draws again from the same generator, up to ``max_attempts`` times. Shards
hold the shapes of fixed index ranges (``shard_size`` indices each) and are
written atomically, so a rerun skips complete shards, and the result does not
depend on the number of worker processes.
"""

from __future__ import annotations

import json
import math
import multiprocessing
import queue as queue_module
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from spacemesh.data.pipeline import prepare_shape
from spacemesh.data.shapes import random_solid
from spacemesh.data.shards import SHARD_PATTERN, write_manifest, write_shard
from spacemesh.data.styles import STYLES, segments_for, tessellate

#: Bumped whenever a change alters the shapes generated for a given seed.
GENERATOR_VERSION = "1.1.0"
PARAMETERS = "synth.json"


@dataclass(frozen=True)
class SynthConfig:
    """What to generate.

    Parameters
    ----------
    count : int
        Shape indices to generate (``0 .. count - 1``); an index whose attempts
        are all rejected is left out and listed as failed.
    seed : int
    style : str
        One of :data:`spacemesh.data.styles.STYLES`.
    vertex_min, vertex_max : int
        Inclusive range of vertex counts; targets are drawn uniformly in it.
    points : int
        Conditioning points per shape.
    shard_size : int
        Shape indices per shard (the unit of resumption).
    max_attempts : int
        Attempts per index before it is given up.
    """

    count: int
    seed: int = 0
    style: str = "qem"
    vertex_min: int = 128
    vertex_max: int = 512
    points: int = 2048
    shard_size: int = 256
    max_attempts: int = 10

    def __post_init__(self) -> None:
        if self.count < 1:
            raise ValueError("count must be at least 1")
        if self.style not in STYLES:
            raise ValueError(f"unknown style {self.style!r}; choose from {', '.join(STYLES)}")
        if not 4 <= self.vertex_min <= self.vertex_max:
            raise ValueError("the vertex range must satisfy 4 <= MIN <= MAX")
        if self.points < 1 or self.shard_size < 1 or self.max_attempts < 1:
            raise ValueError("points, shard size and attempts must be positive")

    @property
    def n_shards(self) -> int:
        """Number of shards of the full run."""
        return math.ceil(self.count / self.shard_size)

    def shard_range(self, k: int) -> range:
        """Shape indices of shard ``k``."""
        return range(k * self.shard_size, min((k + 1) * self.shard_size, self.count))


def make_shape(config: SynthConfig, index: int) -> tuple[dict | None, Counter, int]:
    """Generate shape ``index`` (deterministically), retrying rejected attempts.

    Parameters
    ----------
    config : SynthConfig
    index : int

    Returns
    -------
    shape : dict or None
        See :func:`spacemesh.data.pipeline.prepare_shape`; None when every attempt failed.
    rejections : collections.Counter
        Causes of the rejected attempts.
    attempts : int
    """
    rng = np.random.default_rng([config.seed, index])
    rejections: Counter = Counter()
    shape_id = f"{config.style}-s{config.seed}-{index:07d}"
    for attempt in range(config.max_attempts):
        target = int(rng.integers(config.vertex_min, config.vertex_max + 1))
        try:
            solid, recipe = random_solid(rng, segments_for(config.style, target, rng))
        except Exception:  # a random construction manifold3d cannot build
            rejections["csg_error"] += 1
            continue
        if solid.is_empty():
            rejections["empty_solid"] += 1
            continue
        try:
            mesh = tessellate(config.style, solid, target, rng)
        except Exception:  # native remeshers fail in many ways
            rejections["tessellation_error"] += 1
            continue
        shape, causes = prepare_shape(
            mesh,
            shape_id=shape_id,
            style=config.style,
            rng=rng,
            n_points=config.points,
            vertex_range=(config.vertex_min, config.vertex_max),
            extra={
                "index": index,
                "attempt": attempt,
                "target_vertices": target,
                "recipe": recipe.to_dict(),
            },
        )
        if shape is not None:
            return shape, rejections, attempt + 1
        rejections.update(causes)
    return None, rejections, config.max_attempts


_progress_queue = None


def _init_worker(progress_queue) -> None:
    global _progress_queue
    _progress_queue = progress_queue


def build_shard(config: SynthConfig, out: Path, k: int, report=None) -> dict:
    """Generate and write shard ``k``.

    Parameters
    ----------
    config : SynthConfig
    out : Path
    k : int
    report : callable, optional
        Called as ``report(stored: bool, n_rejected_attempts: int)`` after each shape.

    Returns
    -------
    dict
        The shard summary.
    """
    shapes: list[dict] = []
    rejections: Counter[str] = Counter()
    failed: list[int] = []
    attempts = 0
    for index in config.shard_range(k):
        shape, rejected, n = make_shape(config, index)
        attempts += n
        rejections.update(rejected)
        if shape is None:
            failed.append(index)
        else:
            shapes.append(shape)
        if report is not None:
            report(shape is not None, n - (shape is not None))
    summary = {
        "shard": k,
        "first_index": config.shard_range(k).start,
        "indices": len(config.shard_range(k)),
        "count": len(shapes),
        "attempts": attempts,
        "failed_indices": failed,
        "rejections": dict(sorted(rejections.items())),
    }
    write_shard(out / SHARD_PATTERN.format(k), shapes, summary)
    return summary


def _shard_task(args: tuple[dict, str, int]) -> int:
    config_dict, out, k = args

    def report(stored: bool, rejected: int) -> None:
        if _progress_queue is not None:
            _progress_queue.put((stored, rejected))

    build_shard(SynthConfig(**config_dict), Path(out), k, report)
    return k


def _check_parameters(out: Path, config: SynthConfig) -> None:
    """Record the run's parameters, or refuse to mix a folder's shards with others."""
    path = out / PARAMETERS
    wanted = {"generator_version": GENERATOR_VERSION, **asdict(config)}
    if path.exists():
        existing = json.loads(path.read_text())
        if existing != wanted:
            diff = sorted(k for k in wanted if existing.get(k) != wanted[k])
            raise ValueError(
                f"{out} holds a dataset generated with other parameters ({', '.join(diff)}); "
                "use another --out or the same parameters to resume"
            )
    else:
        path.write_text(json.dumps(wanted, sort_keys=True, indent=2))


def synthesize(
    config: SynthConfig, out: str | Path, *, workers: int = 1, progress: bool = True
) -> dict:
    """Generate (or finish generating) a dataset in ``out``.

    Parameters
    ----------
    config : SynthConfig
    out : path
        Dataset folder; created when missing. Complete shards already there are kept.
    workers : int
        Worker processes (1 runs in this process).
    progress : bool
        Show a progress bar on stderr.

    Returns
    -------
    dict
        The manifest (also written to ``out/manifest.json``), with the run's
        ``elapsed_s`` added (not written, so the file stays reproducible).
    """
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _check_parameters(out, config)
    for stale in out.glob(".shard-*.tmp"):
        stale.unlink()
    todo = [k for k in range(config.n_shards) if not (out / SHARD_PATTERN.format(k)).exists()]
    done = config.count - sum(len(config.shard_range(k)) for k in todo)
    start = time.perf_counter()
    bar = tqdm(total=config.count, initial=done, unit="shape", disable=not progress, smoothing=0.05)
    rejected = 0

    def report(stored: bool, n_rejected: int) -> None:
        nonlocal rejected
        rejected += n_rejected
        bar.update(1)
        bar.set_postfix(rejected=rejected, refresh=False)

    try:
        if workers <= 1 or len(todo) <= 1:
            for k in todo:
                build_shard(config, out, k, report)
        else:
            context = multiprocessing.get_context("spawn")
            progress_queue = context.Queue()
            tasks = [(asdict(config), str(out), k) for k in todo]
            with context.Pool(
                min(workers, len(todo)), initializer=_init_worker, initargs=(progress_queue,)
            ) as pool:
                pending = pool.map_async(_shard_task, tasks, chunksize=1)
                while not pending.ready():
                    _drain(progress_queue, report, timeout=0.2)
                pending.get()
                _drain(progress_queue, report, timeout=0.5)
    finally:
        bar.close()
    header = {
        "generator_version": GENERATOR_VERSION,
        "source": "synth",
        "seed": config.seed,
        "style": config.style,
        "vertex_range": [config.vertex_min, config.vertex_max],
        "points": config.points,
        "count_requested": config.count,
        "shard_size": config.shard_size,
        "max_attempts": config.max_attempts,
    }
    files = [SHARD_PATTERN.format(k) for k in range(config.n_shards)]
    manifest = write_manifest(out, header, files)
    manifest["elapsed_s"] = time.perf_counter() - start
    return manifest


def _drain(progress_queue, report, timeout: float) -> None:
    """Pass every queued progress event to ``report``, waiting at most ``timeout`` first."""
    try:
        event = progress_queue.get(timeout=timeout)
    except queue_module.Empty:
        return
    report(*event)
    while True:
        try:
            event = progress_queue.get_nowait()
        except queue_module.Empty:
            return
        report(*event)
