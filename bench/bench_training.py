"""Training throughput: steps/s and shapes/s of the joint loop and of diffusion-only runs.

Usage::

    OMP_NUM_THREADS=1 .venv/bin/python bench/bench_training.py --data data/qem-small-s1 \\
        [--base models/spacemesh-small/7] [--threads 1] [--steps 6] [--modes joint,cached]

Every row builds the real :class:`spacemesh.train.loop.Trainer` on the ``small`` config
(the shipped one) and times ``Trainer.train_step``, data loading included (batch
selection, augmentation, collation, the encoder cache's lookups), after one warm-up
step. Loading the dataset once (``load_samples``) is not a step and is printed apart.
Rows:

``joint``
    The loop that trained the shipped model: one diffusion step (encoder and denoiser
    trained) and ten connectivity steps per step.
``diffusion``
    Diffusion steps only, encoder trained (``connectivity_steps = 0``).
``frozen``
    Diffusion-only, the base's frozen encoder run on every batch (no cache).
``cached``
    Diffusion-only with the encoder cache, filled beforehand (the steady state: each
    variant's volumes are computed once per run, the fill cost is printed apart).
``cached-b24``, ``cached-b48``
    The same at batch 24 and 48.
``local``, ``local-b24``
    The local-point denoiser (``small-local``) on the cache, at batch 6 and 24.

"shapes/s" counts the shapes the denoiser sees (``joint``: the diffusion batch; the
connectivity steps are the rest of its cost). One JSON line per row: the median step
and the fastest one (on a shared machine the fastest is the least disturbed).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

#: Rows: (name, config name, batch, diffusion only, cache variants, connectivity steps).
MODES = {
    "joint": ("small", 6, False, 0, 10),
    "diffusion": ("small", 6, False, 0, 0),
    "frozen": ("small", 6, True, 0, 0),
    "cached": ("small", 6, True, 1, 0),
    "cached-b24": ("small", 24, True, 1, 0),
    "cached-b48": ("small", 48, True, 1, 0),
    "local": ("small-local", 6, True, 1, 0),
    "local-b24": ("small-local", 24, True, 1, 0),
}


def _trainer(mode: str, data: Path, base: Path, out: Path):
    from spacemesh.nn.config import get_config
    from spacemesh.train.distributed import setup_distributed
    from spacemesh.train.loop import Trainer, TrainOptions

    name, batch, diffusion_only, variants, connectivity_steps = MODES[mode]
    config = get_config(name).with_train(
        batch_size=batch, diffusion_only=diffusion_only, encoder_cache=variants,
        connectivity_steps=connectivity_steps, val_shapes=1,
    )
    options = TrainOptions(config=config, data=data, out=out, progress=False, device="cpu",
                           base=base if diffusion_only else None)
    return Trainer(options, setup_distributed("cpu"), log=lambda m: None)


def _fill(trainer) -> float:
    """Compute every cached variant once; returns the seconds it took."""
    cache = trainer.cache
    start = time.perf_counter()
    batch = trainer.config.train.batch_size
    for variant in range(cache.variants):
        order = list(range(len(trainer.train_samples)))
        for i in range(0, len(order), batch):
            keys = [(j, variant) for j in order[i : i + batch]]
            cache.fill(keys)
    return time.perf_counter() - start


def main() -> None:
    """Run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="dataset (its train split)")
    parser.add_argument("--base", type=Path, default=Path("models/spacemesh-small/7"),
                        help="frozen encoder of the diffusion-only rows")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--steps", type=int, default=6, help="timed steps per row")
    parser.add_argument("--modes", default=",".join(MODES))
    args = parser.parse_args()

    import torch

    torch.set_num_threads(args.threads)
    for mode in args.modes.split(","):
        if mode not in MODES:
            raise SystemExit(f"unknown mode {mode!r}; choose from {', '.join(MODES)}")
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            trainer = _trainer(mode, args.data, args.base, Path(tmp) / "run")
            setup = time.perf_counter() - start
            fill = _fill(trainer) if trainer.cache is not None else 0.0
            running: dict[str, list[float]] = defaultdict(list)
            trainer.model.train()
            trainer.train_step(0, running)  # warm-up
            times = []
            for step in range(1, args.steps + 1):
                start = time.perf_counter()
                trainer.train_step(step, running)
                times.append(time.perf_counter() - start)
        batch = trainer.config.train.batch_size
        seconds, best = float(np.median(times)), min(times)
        print(json.dumps({
            "mode": mode, "config": trainer.config.name, "batch": batch,
            "threads": args.threads, "s_per_step": round(seconds, 4),
            "s_per_step_min": round(best, 4), "steps_per_s": round(1.0 / seconds, 3),
            "shapes_per_s": round(batch / seconds, 2),
            "shapes_per_s_best": round(batch / best, 2),
            "train_shapes": len(trainer.train_samples), "setup_s": round(setup, 1),
            "cache_fill_s": round(fill, 1),
            "cache_fill_ms_per_shape": round(1000 * fill / max(len(trainer.train_samples), 1), 1),
        }), flush=True)


if __name__ == "__main__":
    main()
