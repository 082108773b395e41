"""Gaussian diffusion over vertex tokens in torch: ``q_sample``, training targets, and the
torch reference sampler.

The schedule is computed once, in numpy (:mod:`spacemesh.runtime.schedule`), and only
converted here, so training and the onnxruntime service cannot disagree about it. The
reference sampler is the runtime's numpy loop driven by the torch denoiser: with the same
seeds it follows exactly the path the exported model follows.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from spacemesh.runtime.sampler import ProgressFn, sample
from spacemesh.runtime.schedule import NoiseSchedule


def vertex_tokens(positions: Tensor, valid: Tensor) -> Tensor:
    """Clean diffusion tokens ``x_0`` ``(B, N, 4)``: positions (zero for padding) and mask.

    Parameters
    ----------
    positions : (B, N, 3) tensor
    valid : (B, N) bool tensor

    Returns
    -------
    (B, N, 4) tensor
        The mask channel is ``1`` for real vertices and ``-1`` for padding.
    """
    mask = valid.to(positions.dtype) * 2.0 - 1.0
    return torch.cat([positions * valid[..., None], mask[..., None]], dim=-1)


class GaussianDiffusion:
    """The forward process and the epsilon-prediction losses.

    Parameters
    ----------
    schedule : str
        ``cosine`` or ``linear``.
    timesteps : int
    """

    def __init__(self, *, schedule: str, timesteps: int) -> None:
        self.schedule = NoiseSchedule.from_config(schedule, timesteps)
        self.timesteps = timesteps
        self._abar = torch.as_tensor(self.schedule.alphas_cumprod, dtype=torch.float32)

    def q_sample(self, x0: Tensor, t: Tensor, noise: Tensor) -> Tensor:
        """``x_t = sqrt(abar_t) x_0 + sqrt(1 - abar_t) eps`` for ``x_0`` ``(B, N, C)``."""
        abar = self._abar.to(x0.device)[t].reshape(-1, 1, 1)  # (B, 1, 1)
        return abar.sqrt() * x0 + (1.0 - abar).sqrt() * noise

    def training_losses(
        self, denoiser, x0: Tensor, volumes: list[Tensor], generator: torch.Generator | None = None
    ) -> dict[str, Tensor]:
        """Epsilon losses at uniformly drawn timesteps.

        Parameters
        ----------
        denoiser : callable
            ``(x_t, t, volumes) -> eps``.
        x0 : (B, N, 4) tensor
            From :func:`vertex_tokens`.
        volumes : list of tensors
        generator : torch.Generator, optional

        Returns
        -------
        dict
            ``epsilon``: MSE on the position channels; ``mask``: MSE on the mask channel.
        """
        b = x0.shape[0]
        t = torch.randint(0, self.timesteps, (b,), generator=generator).to(x0.device)
        noise = torch.randn(x0.shape, generator=generator).to(x0.device)
        eps = denoiser(self.q_sample(x0, t, noise), t, volumes).float()  # (B, N, 4)
        return {
            "epsilon": F.mse_loss(eps[..., :3], noise[..., :3]),
            "mask": F.mse_loss(eps[..., 3], noise[..., 3]),
        }

    @torch.no_grad()
    def sample(
        self,
        denoiser,
        volumes: list[Tensor],
        *,
        seeds: Sequence[int],
        n_vertices: int,
        steps: int,
        method: str = "ddim",
        progress: ProgressFn | None = None,
    ) -> np.ndarray:
        """The torch reference sampler (the runtime loop over the torch denoiser).

        Parameters
        ----------
        denoiser : callable
            ``(x_t, t, volumes) -> eps`` in torch.
        volumes : list of (B, C, R, R, R) tensors
        seeds : sequence of int
            One per batch item.
        n_vertices, steps : int
        method : {"ddim", "ddpm"}
        progress : callable, optional

        Returns
        -------
        (B, N, 4) float32 numpy array
        """
        device = volumes[0].device

        def denoise(x: np.ndarray, t: np.ndarray) -> np.ndarray:
            eps = denoiser(torch.as_tensor(x, device=device), torch.as_tensor(t, device=device),
                           volumes)
            return eps.float().cpu().numpy()

        return sample(
            denoise, seeds=seeds, n_vertices=n_vertices, steps=self.schedule.respaced(steps),
            method=method, progress=progress,
        )
