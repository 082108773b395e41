"""The torch diffusion: forward process, losses, and the reference sampler."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.diffusion import GaussianDiffusion, vertex_tokens  # noqa: E402
from spacemesh.runtime.sampler import sample  # noqa: E402


def test_vertex_tokens_zero_padding_and_mask_channel():
    positions = torch.ones(1, 3, 3)
    valid = torch.tensor([[True, True, False]])
    x0 = vertex_tokens(positions, valid)
    assert x0[0, :, 3].tolist() == [1.0, 1.0, -1.0]
    assert x0[0, 2, :3].abs().sum() == 0


def test_q_sample_matches_the_closed_form():
    diffusion = GaussianDiffusion(schedule="linear", timesteps=100)
    x0 = torch.randn(2, 5, 4)
    noise = torch.randn(2, 5, 4)
    t = torch.tensor([0, 99])
    abar = diffusion.schedule.alphas_cumprod
    x_t = diffusion.q_sample(x0, t, noise)
    for b in range(2):
        expected = np.sqrt(abar[t[b]]) * x0[b] + np.sqrt(1 - abar[t[b]]) * noise[b]
        assert torch.allclose(x_t[b], expected.float(), atol=1e-6)


def test_training_losses_of_a_perfect_denoiser_are_zero():
    diffusion = GaussianDiffusion(schedule="cosine", timesteps=50)
    x0 = torch.randn(3, 7, 4)
    gen = torch.Generator().manual_seed(0)
    captured = {}

    def oracle(x_t, t, volumes):
        abar = torch.as_tensor(diffusion.schedule.alphas_cumprod, dtype=torch.float32)[t]
        abar = abar.reshape(-1, 1, 1)
        captured["eps"] = (x_t - abar.sqrt() * x0) / (1 - abar).sqrt()
        return captured["eps"]

    losses = diffusion.training_losses(oracle, x0, [], gen)
    assert float(losses["epsilon"]) < 1e-8 and float(losses["mask"]) < 1e-8


def test_reference_sampler_is_the_runtime_loop():
    diffusion = GaussianDiffusion(schedule="cosine", timesteps=64)

    def denoiser(x, t, volumes):
        return 0.1 * x + 0.001 * t.float()[:, None, None]

    ours = diffusion.sample(denoiser, [torch.zeros(2, 1, 2, 2, 2)], seeds=[3, 4], n_vertices=6,
                            steps=8, method="ddpm")

    def numpy_denoise(x, t):
        return 0.1 * x + 0.001 * t[:, None, None]

    ref = sample(numpy_denoise, seeds=[3, 4], n_vertices=6,
                 steps=diffusion.schedule.respaced(8), method="ddpm")
    assert np.allclose(ours, ref, atol=1e-6)
