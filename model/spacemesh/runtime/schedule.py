"""The diffusion noise schedule and sampler steps, in numpy (no torch).

Training uses ``T`` timesteps with betas from :func:`make_betas`. Sampling may use any
subset of them (respacing, as in improved DDPM): for timesteps ``t_S > ... > t_1`` the
respaced process has ``alpha_bar`` equal to the trained one at those timesteps, so the
trained denoiser is called with the original timestep values. Two updates are offered:

``ddpm``
    Ancestral sampling with the posterior variance of the (respaced) process. With
    ``steps == T`` this is the original DDPM sampler.
``ddim``
    The deterministic DDIM update (``eta = 0``): only the initial noise is random.

Both clip the predicted ``x_0`` to ``[-1, 1]`` (positions are normalised to that cube
and the mask channel is +-1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spacemesh.typed import FloatArray, IntArray

SCHEDULES = ("cosine", "linear")
METHODS = ("ddim", "ddpm")


def make_betas(kind: str, timesteps: int) -> FloatArray:
    """Betas of a named schedule.

    Parameters
    ----------
    kind : {"cosine", "linear"}
        ``linear``: DDPM's 1e-4 .. 0.02 rescaled to ``T`` steps; ``cosine``: the improved
        DDPM schedule (betas capped at 0.999).
    timesteps : int

    Returns
    -------
    (T,) float64
    """
    if kind == "linear":
        scale = 1000.0 / timesteps
        return np.linspace(scale * 1e-4, scale * 0.02, timesteps, dtype=np.float64)
    if kind == "cosine":

        def alpha_bar(t: float) -> float:
            return math.cos((t + 0.008) / 1.008 * math.pi / 2) ** 2

        return np.array(
            [
                min(1.0 - alpha_bar((i + 1) / timesteps) / alpha_bar(i / timesteps), 0.999)
                for i in range(timesteps)
            ],
            dtype=np.float64,
        )
    raise ValueError(f"unknown schedule {kind!r}; choose from {', '.join(SCHEDULES)}")


def spaced_timesteps(timesteps: int, steps: int) -> IntArray:
    """``steps`` trained timesteps spread evenly over ``0 .. T - 1``, ascending.

    Parameters
    ----------
    timesteps : int
        ``T``.
    steps : int
        At least 1, at most ``T``.

    Returns
    -------
    (S,) int64
        Always contains ``0`` and ``T - 1``.
    """
    if not 1 <= steps <= timesteps:
        raise ValueError(f"steps must be in 1..{timesteps}, not {steps}")
    if steps == 1:
        return np.array([timesteps - 1], dtype=np.int64)
    return np.unique(np.round(np.linspace(0, timesteps - 1, steps)).astype(np.int64))


@dataclass(frozen=True)
class NoiseSchedule:
    """A trained schedule: ``betas`` ``(T,)`` and the quantities derived from them."""

    betas: FloatArray

    @classmethod
    def from_config(cls, kind: str, timesteps: int) -> NoiseSchedule:
        """The schedule :func:`make_betas` builds."""
        return cls(make_betas(kind, timesteps))

    @property
    def timesteps(self) -> int:
        """``T``."""
        return len(self.betas)

    @property
    def alphas_cumprod(self) -> FloatArray:
        """(T,) ``alpha_bar_t``."""
        return np.cumprod(1.0 - np.asarray(self.betas, dtype=np.float64))

    def respaced(self, steps: int) -> SamplingSteps:
        """The sampling steps of a respaced process with ``steps`` steps."""
        t = spaced_timesteps(self.timesteps, steps)
        abar = self.alphas_cumprod[t]
        abar_prev = np.concatenate([[1.0], abar[:-1]])
        return SamplingSteps(timesteps=t, alphas_cumprod=abar, alphas_cumprod_prev=abar_prev)


@dataclass(frozen=True)
class SamplingSteps:
    """A respaced process, ascending in time (index 0 is the last step taken).

    Attributes
    ----------
    timesteps : (S,) int64
        Trained timesteps passed to the denoiser.
    alphas_cumprod, alphas_cumprod_prev : (S,) float64
    """

    timesteps: IntArray
    alphas_cumprod: FloatArray
    alphas_cumprod_prev: FloatArray

    def __len__(self) -> int:
        return len(self.timesteps)

    def predict_x0(self, i: int, x_t: FloatArray, eps: FloatArray) -> FloatArray:
        """Clipped ``x_0`` implied by ``eps`` at step ``i``."""
        abar = self.alphas_cumprod[i]
        x0 = (x_t - math.sqrt(1.0 - abar) * eps) / math.sqrt(abar)
        return np.clip(x0, -1.0, 1.0)

    def ddim_step(self, i: int, x_t: FloatArray, eps: FloatArray) -> FloatArray:
        """``x_{t_{i-1}}`` by the deterministic DDIM update (``eta = 0``)."""
        abar, abar_prev = self.alphas_cumprod[i], self.alphas_cumprod_prev[i]
        x0 = self.predict_x0(i, x_t, eps)
        eps = (x_t - math.sqrt(abar) * x0) / math.sqrt(1.0 - abar)  # consistent with the clip
        return math.sqrt(abar_prev) * x0 + math.sqrt(1.0 - abar_prev) * eps

    def ddpm_mean_std(self, i: int, x_t: FloatArray, eps: FloatArray) -> tuple[FloatArray, float]:
        """Mean and standard deviation of the posterior ``q(x_{t_{i-1}} | x_t, x_0)``."""
        abar, abar_prev = self.alphas_cumprod[i], self.alphas_cumprod_prev[i]
        beta = 1.0 - abar / abar_prev
        x0 = self.predict_x0(i, x_t, eps)
        c0 = beta * math.sqrt(abar_prev) / (1.0 - abar)
        ct = (1.0 - abar_prev) * math.sqrt(1.0 - beta) / (1.0 - abar)
        var = beta * (1.0 - abar_prev) / (1.0 - abar)
        return c0 * x0 + ct * x_t, math.sqrt(max(var, 0.0))
