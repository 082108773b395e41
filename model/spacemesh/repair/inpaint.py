"""Diffusion inpainting of vertex tokens with known vertices held (paper, Supplement D).

All ``N`` tokens start as noise. At every step ``t``:

1. **Align** the tokens to the targets ``Y = [known vertices; hole points]`` (``K``
   known vertices padded with ``N - K`` points sampled in the hole, so both sets have
   ``N`` elements). The cost is ``C[i, j] = |x_t[j] - sqrt(abar_t) y_i|^2`` (the
   targets scaled to where the forward process puts them at ``t``; at ``t = 0`` it is
   the paper's ``|x_t[j] - y_i|^2``). Sinkhorn turns ``exp(-C / T)`` into the soft
   correspondence ``C_bar`` and the optimal assignment on ``-log C_bar``
   (``scipy.optimize.linear_sum_assignment``) gives the hard one. Sinkhorn's row and
   column scalings add the same constant to every permutation's cost, so this is also
   the optimal assignment of the squared distances themselves.
2. **Replace** each token matched to a known vertex by ``q(x_t | x_0)``: the known
   position with mask channel +1, scaled by ``sqrt(abar_t)``, plus fresh noise of
   variance ``1 - abar_t``. Tokens matched to hole points stay free.
3. **Denoise** every token one step (DDIM or DDPM, :mod:`spacemesh.runtime.schedule`).

After the last step the tokens are aligned once more (``t = 0``) and the matched ones
set exactly to the known vertices. Free tokens whose mask channel is positive are the
candidate new vertices; the mask channel marks the rest as padding. Everything random
comes from one ``numpy.random.Generator`` seeded by the caller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from spacemesh.cancel import checkpoint
from spacemesh.permutation import log_sinkhorn
from spacemesh.runtime.backend import Backend, denoiser_fn
from spacemesh.runtime.sampler import ProgressFn, reverse_step
from spacemesh.runtime.schedule import METHODS, SamplingSteps
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: Sinkhorn temperature, relative to the mean squared distance of the cost matrix.
ALIGN_TEMPERATURE = 0.05
#: Sinkhorn rounds of the alignment (they do not change the hard assignment, see the
#: module docstring; a few keep the soft correspondence meaningful).
ALIGN_SINKHORN_ITERS = 5


@dataclass(frozen=True)
class InpaintResult:
    """Tokens after inpainting.

    Attributes
    ----------
    tokens : (N, 4) float32
        Positions (unit frame) and mask channel.
    known_token : (K,) int64
        The token holding each known vertex.
    free : (N,) bool
        Tokens not holding a known vertex.
    alive : (N,) bool
        Free tokens whose mask channel is positive (candidate new vertices).
    """

    tokens: np.ndarray
    known_token: IntArray
    free: BoolArray
    alive: BoolArray


def align(positions: FloatArray, targets: FloatArray, scale: float = 1.0) -> IntArray:
    """Optimal one-to-one correspondence between tokens and targets.

    Parameters
    ----------
    positions : (N, 3) float
        Token positions ``x_t``.
    targets : (N, 3) float
        Known vertices then hole points.
    scale : float
        ``sqrt(abar_t)``: targets are compared at ``scale * y``.

    Returns
    -------
    (N,) int64
        ``token[i]``: the token matched to target ``i``.
    """
    x = np.asarray(positions, np.float64)
    y = scale * np.asarray(targets, np.float64)
    cost = np.sum((y[:, None, :] - x[None, :, :]) ** 2, axis=-1)  # (N_targets, N_tokens)
    temperature = max(ALIGN_TEMPERATURE * float(cost.mean()), 1e-12)
    log_soft = log_sinkhorn(-cost[None] / temperature, ALIGN_SINKHORN_ITERS)[0]  # (N, N)
    rows, cols = linear_sum_assignment(-log_soft)
    token = np.empty(len(targets), dtype=np.int64)
    token[rows] = cols
    return token


def inpaint_tokens(
    backend: Backend,
    volumes: list[np.ndarray],
    known: FloatArray,
    hole_points: FloatArray,
    steps: SamplingSteps,
    *,
    method: str,
    rng: np.random.Generator,
    progress: ProgressFn | None = None,
    points: FloatArray | None = None,
) -> InpaintResult:
    """Run the inpainting sampler (algorithm in the module docstring).

    Parameters
    ----------
    backend : Backend
        ``denoise(x_t (1, N, 4), t (1,), volumes[, points]) -> eps (1, N, 4)``.
    volumes : list of arrays
        Encoder output for the conditioning points (batch of one).
    known : (K, 3) float
        Known vertices, unit frame.
    hole_points : (N - K, 3) float
        Padding targets sampled in the hole, unit frame.
    steps : SamplingSteps
        From :meth:`spacemesh.runtime.schedule.NoiseSchedule.respaced`.
    method : {"ddim", "ddpm"}
    rng : numpy.random.Generator
    progress : callable, optional
        ``progress(done, total)`` after each denoiser step.
    points : (1, P, 3 or 6) float, optional
        The conditioning points (the encoder's input), for a local-point denoiser
        (``ModelSpec.local_points > 0``); None for one that reads the volumes only.

    Returns
    -------
    InpaintResult
    """
    if method not in METHODS:
        raise ValueError(f"unknown sampler {method!r}; choose from {', '.join(METHODS)}")
    known = np.asarray(known, np.float64).reshape(-1, 3)
    n_known = len(known)
    targets = np.concatenate([known, np.asarray(hole_points, np.float64).reshape(-1, 3)])
    n = len(targets)
    known_x0 = np.concatenate([known, np.ones((n_known, 1))], axis=1)  # (K, 4)
    x: FloatArray = rng.standard_normal((n, 4))  # (N, 4)
    denoise = denoiser_fn(backend, volumes, points)
    total = len(steps)
    for done, i in enumerate(reversed(range(total)), start=1):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        abar = float(steps.alphas_cumprod[i])
        token = align(x[:, :3], targets, math.sqrt(abar))[:n_known]
        noise = rng.standard_normal((n_known, 4))
        x[token] = math.sqrt(abar) * known_x0 + math.sqrt(1.0 - abar) * noise
        t = np.full(1, steps.timesteps[i], dtype=np.int64)
        eps = np.asarray(denoise(x[None].astype(np.float32), t), np.float64)[0]  # (N, 4)
        x = reverse_step(steps, i, x, eps, method, lambda: rng.standard_normal((n, 4)))
        if progress is not None:
            progress(done, total)
    token = align(x[:, :3], targets)[:n_known]
    x[token] = known_x0
    free = np.ones(n, dtype=bool)
    free[token] = False
    return InpaintResult(x.astype(np.float32), token, free, free & (x[:, 3] > 0.0))
