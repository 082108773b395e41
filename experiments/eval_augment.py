"""Denoiser error on clean and degraded conditioning clouds, by timestep band.

For each run (a diffusion-only run folder or checkpoint), the epsilon error (MSE on the
position channels) of the real vertices' tokens on the val split of ``--data``, in three
timestep bands, with the conditioning cloud clean or degraded by
:mod:`spacemesh.data.augment` (the ``realistic`` preset, and each kind of degradation on
its own, stronger than the preset). Every model sees the same shapes, clouds, timesteps
and noise. docs/MODEL.md's realistic-data table came from::

    python experiments/eval_augment.py --data DATA RUN_NONE RUN_REALISTIC
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch

from spacemesh.data.augment import AugmentConfig, get_augment
from spacemesh.export.repository import load_trained_model
from spacemesh.nn.diffusion import vertex_tokens
from spacemesh.train.batching import collate
from spacemesh.train.loop import load_samples

#: condition -> augmentation of the val clouds (None: clean)
CONDITIONS: dict[str, AugmentConfig | None] = {
    "clean": None,
    "realistic": get_augment("realistic"),
    "noisy (sd <= 0.03)": AugmentConfig(noise=0.03),
    "partial (scan + cap)": AugmentConfig(scan=1.0, cap=1.0),
    "outliers (<= 10 %)": AugmentConfig(outliers=0.1),
}
#: timestep bands [lo, hi)
BANDS = ((0, 64), (64, 256), (256, 1024))


@torch.no_grad()
def band_errors(run: Path, data: Path, *, batch: int = 8, draws: int = 2,
                ) -> dict[str, list[float]]:
    """Mean epsilon error per band of one run under every condition."""
    model, state = load_trained_model(run)
    config = state["config"]
    val = load_samples(data, "val", config.max_vertices)
    result = {}
    for name, augment in CONDITIONS.items():
        rng = np.random.default_rng(7)
        gen = torch.Generator().manual_seed(11)
        errors: dict[tuple[int, int], list[float]] = {band: [] for band in BANDS}
        for start in range(0, len(val), batch):
            b = collate(val[start:start + batch], n_points=config.encoder.n_points,
                        normals=config.encoder.normals, pad_to=config.max_vertices,
                        connectivity=False, rng=rng, augment=augment)
            volumes = model.encoder(b.points)
            x0 = vertex_tokens(b.positions, b.valid)
            for lo, hi in BANDS:
                for _ in range(draws):
                    t = torch.randint(lo, hi, (len(x0),), generator=gen)
                    noise = torch.randn(x0.shape, generator=gen)
                    eps = model.denoiser(model.diffusion.q_sample(x0, t, noise), t, volumes,
                                         b.points)
                    err = ((eps[..., :3] - noise[..., :3]) ** 2).mean(-1)[b.valid]
                    errors[(lo, hi)].append(float(err.mean()))
        result[name] = [round(float(np.mean(errors[band])), 4) for band in BANDS]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+", help="run folders or checkpoints")
    parser.add_argument("--data", type=Path, required=True, help="dataset (its val split)")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    out = {str(run): band_errors(run, args.data) for run in args.runs}
    bands = " | ".join(f"t in [{lo}, {hi})" for lo, hi in BANDS)
    print(f"| run | clouds | {bands} |\n|---|---|" + "---|" * len(BANDS))
    for run, rows in out.items():
        for name, errs in rows.items():
            print(f"| {Path(run).name} | {name} | " + " | ".join(f"{e:.3f}" for e in errs) + " |")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
