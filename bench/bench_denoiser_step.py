"""Latency of one denoiser step in onnxruntime (the unit of the sampler loop).

Usage::

    .venv/bin/python bench/bench_denoiser_step.py [--model DIR] [--vertices 512]
        [--batch 1] [--threads 2] [--repeats 20]

Without ``--model`` it measures the shipped model (``models/spacemesh-small``, its
highest version). With ``--config small`` instead it exports a randomly initialised model
of that config first (needs torch), which is how the width-128 latency is measured before
any training. Prints one JSON line: the median and 90th percentile of a step, in milliseconds.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def _exported(config: str, directory: Path) -> Path:
    from spacemesh.export.repository import write_model_repository
    from spacemesh.nn.model import model_from_config

    return write_model_repository(model_from_config(config), directory, name=f"bench-{config}")


def main() -> None:
    """Run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--config", default=None, help="export a fresh model of this config")
    parser.add_argument("--vertices", type=int, default=512)
    parser.add_argument("--batch", type=int, default=1)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()

    from spacemesh.runtime import ModelRepository

    with tempfile.TemporaryDirectory() as tmp:
        path = _exported(args.config, Path(tmp)) if args.config else args.model
        repo = ModelRepository.load(path, threads=args.threads)
        backend = repo.backend
        rng = np.random.default_rng(0)
        n_points = repo.manifest["inputs"]["n_points"]
        points = rng.uniform(-1, 1, (args.batch, n_points, 3)).astype(np.float32)
        t0 = time.perf_counter()
        volumes = backend.encode(points)
        encoder_ms = (time.perf_counter() - t0) * 1e3
        x = rng.normal(size=(args.batch, args.vertices, 4)).astype(np.float32)
        t = np.full(args.batch, 500, dtype=np.int64)
        backend.denoise(x, t, volumes)  # warm-up
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            backend.denoise(x, t, volumes)
            times.append((time.perf_counter() - start) * 1e3)
        files = repo.manifest["files"]
        print(json.dumps({
            "model": repo.name,
            "width": repo.config["denoiser"]["width"],
            "layers": repo.config["denoiser"]["layers"],
            "vertices": args.vertices,
            "batch": args.batch,
            "threads": args.threads,
            "step_ms_median": round(float(np.median(times)), 2),
            "step_ms_p90": round(float(np.percentile(times, 90)), 2),
            "encoder_ms": round(encoder_ms, 2),
            "onnx_mb": round(sum(f["bytes"] for f in files.values()) / 2**20, 2),
        }))


if __name__ == "__main__":
    main()
