"""The seeded sampler loop over a denoiser, in numpy (the loop is not in any graph).

The denoiser is any function ``(x_t (B, N, 4) float32, t (B,) int64) -> eps (B, N, 4)``:
an onnxruntime session in the service, the torch network in tests and training.
Each request of a batch draws its noise from its own ``numpy.random.Generator`` seeded
with its seed, in a fixed order, so a request gives the same result alone or batched,
and the same result whichever backend evaluates the denoiser.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from spacemesh.runtime.schedule import METHODS, SamplingSteps
from spacemesh.typed import BoolArray, FloatArray

#: ``denoise(x_t, t) -> eps``.
DenoiseFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
#: ``progress(done, total)``, called after every denoiser step.
ProgressFn = Callable[[int, int], None]
#: ``stage(name, done, total)``, called as a pipeline stage begins (the ``done``-th of
#: ``total`` times; :meth:`spacemesh.runtime.pipeline.MeshGenerator.generate_batch`).
StageFn = Callable[[str, int, int], None]


def sample(
    denoise: DenoiseFn,
    *,
    seeds: Sequence[int],
    n_vertices: int,
    steps: SamplingSteps,
    method: str = "ddim",
    progress: ProgressFn | None = None,
    start: FloatArray | None = None,
    start_time: float = 1.0,
) -> FloatArray:
    """Run the reverse process from pure noise (or from noised tokens) to vertex tokens.

    Parameters
    ----------
    denoise : callable
        ``(x_t (B, N, 4) float32, t (B,) int64) -> eps (B, N, 4)``.
    seeds : sequence of int
        One seed per request; ``B = len(seeds)``.
    n_vertices : int
        Tokens per request ``N`` (the model's maximum vertex count).
    steps : SamplingSteps
        From :meth:`spacemesh.runtime.schedule.NoiseSchedule.respaced`.
    method : {"ddim", "ddpm"}
    progress : callable, optional
        ``progress(done, total)`` after each step.
    start : (B, N, 4) float, optional
        Clean tokens to start from (SDEdit): they are noised to the last step at or
        below ``start_time`` and only the steps from there down run. None: pure noise.
    start_time : float
        Fraction t/T of the diffusion where ``start`` begins (0: returned unchanged).

    Returns
    -------
    (B, N, 4) float32
        Positions and mask channel of each token.
    """
    if method not in METHODS:
        raise ValueError(f"unknown sampler {method!r}; choose from {', '.join(METHODS)}")
    rngs = [np.random.default_rng(int(s)) for s in seeds]
    shape = (n_vertices, 4)
    x = np.stack([r.standard_normal(shape) for r in rngs]).astype(np.float32)  # (B, N, 4)
    total = len(steps)
    if start is not None:
        total = start_steps(steps, start_time)
        if total == 0:
            return np.asarray(start, dtype=np.float32)
        abar = float(steps.alphas_cumprod[total - 1])
        x = (np.sqrt(abar) * np.asarray(start, np.float64)
             + np.sqrt(1.0 - abar) * x).astype(np.float32)
    for done, i in enumerate(reversed(range(total)), start=1):
        t = np.full(len(rngs), steps.timesteps[i], dtype=np.int64)  # (B,)
        eps = np.asarray(denoise(x, t), dtype=np.float64)  # (B, N, 4)
        x = reverse_step(
            steps, i, x.astype(np.float64), eps, method,
            lambda: np.stack([r.standard_normal(shape) for r in rngs]),
        ).astype(np.float32)
        if progress is not None:
            progress(done, total)
    return x


def start_steps(steps: SamplingSteps, start_time: float) -> int:
    """How many of ``steps`` run from ``start_time`` (a fraction t/T): those whose
    timestep is at or below it."""
    limit = float(start_time) * (int(steps.timesteps[-1]) + 1)
    return int(np.count_nonzero(np.asarray(steps.timesteps) < limit))


def reverse_step(
    steps: SamplingSteps,
    i: int,
    x: FloatArray,
    eps: FloatArray,
    method: str,
    noise: Callable[[], FloatArray],
) -> FloatArray:
    """One reverse step from respaced step ``i`` to ``i - 1`` (DDIM, or DDPM with noise).

    Parameters
    ----------
    steps : SamplingSteps
    i : int
        Index into ``steps`` (``len(steps) - 1`` down to 0).
    x, eps : (..., 4) float64 arrays
        Current tokens and the predicted noise.
    method : {"ddim", "ddpm"}
    noise : callable
        Draws the DDPM noise, shaped like ``x``; called only when ``method`` is ``ddpm``
        and ``i > 0`` (so random streams advance exactly as before).

    Returns
    -------
    (..., 4) float64
    """
    if method == "ddim":
        return steps.ddim_step(i, x, eps)
    mean, std = steps.ddpm_mean_std(i, x, eps)
    return mean + std * noise() if i > 0 else mean


def split_tokens(tokens: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Positions ``(B, N, 3)`` and alive mask ``(B, N)`` (mask channel > 0) of tokens."""
    return tokens[..., :3], tokens[..., 3] > 0.0
