"""Noise schedule, respacing and the numpy sampler loop (no torch)."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.runtime.sampler import sample, split_tokens
from spacemesh.runtime.schedule import NoiseSchedule, make_betas, spaced_timesteps


@pytest.mark.parametrize("kind", ["linear", "cosine"])
def test_betas_are_valid(kind):
    betas = make_betas(kind, 1024)
    assert betas.shape == (1024,) and (betas > 0).all() and (betas < 1).all()
    abar = NoiseSchedule(betas).alphas_cumprod
    assert (np.diff(abar) < 0).all() and abar[-1] < 1e-2


def test_unknown_schedule_is_refused():
    with pytest.raises(ValueError):
        make_betas("quadratic", 10)


def test_spacing_keeps_both_ends():
    t = spaced_timesteps(1024, 50)
    assert t[0] == 0 and t[-1] == 1023 and len(t) == 50 and (np.diff(t) > 0).all()
    assert spaced_timesteps(1024, 1).tolist() == [1023]
    assert len(spaced_timesteps(10, 10)) == 10
    with pytest.raises(ValueError):
        spaced_timesteps(10, 11)


def test_full_respacing_is_the_trained_process():
    schedule = NoiseSchedule.from_config("linear", 100)
    steps = schedule.respaced(100)
    implied = 1 - steps.alphas_cumprod / steps.alphas_cumprod_prev
    assert np.allclose(implied, schedule.betas)


def _oracle(x0):
    """A denoiser that knows the answer: eps implied by x0."""

    def denoise(x, t, steps):
        i = np.searchsorted(steps.timesteps, t[0])
        abar = steps.alphas_cumprod[i]
        return (x - np.sqrt(abar) * x0) / np.sqrt(1 - abar)

    return denoise


@pytest.mark.parametrize("method", ["ddim", "ddpm"])
def test_sampler_recovers_the_data_with_an_oracle(method):
    rng = np.random.default_rng(0)
    x0 = np.clip(rng.normal(size=(2, 9, 4)) * 0.3, -1, 1)
    steps = NoiseSchedule.from_config("cosine", 200).respaced(20)
    oracle = _oracle(x0)
    out = sample(lambda x, t: oracle(x, t, steps), seeds=[1, 2], n_vertices=9, steps=steps,
                 method=method)
    assert out.dtype == np.float32 and out.shape == (2, 9, 4)
    assert np.allclose(out, x0, atol=1e-4)


def test_sampler_is_seeded_per_request_and_reports_progress():
    steps = NoiseSchedule.from_config("cosine", 100).respaced(5)

    def denoise(x, t):
        return 0.5 * x

    seen = []
    both = sample(denoise, seeds=[7, 8], n_vertices=4, steps=steps, method="ddpm",
                  progress=lambda done, total: seen.append((done, total)))
    alone = sample(denoise, seeds=[8], n_vertices=4, steps=steps, method="ddpm")
    assert np.array_equal(both[1], alone[0])
    assert seen == [(i, 5) for i in range(1, 6)]
    positions, alive = split_tokens(both)
    assert positions.shape == (2, 4, 3) and alive.dtype == bool
    with pytest.raises(ValueError):
        sample(denoise, seeds=[1], n_vertices=4, steps=steps, method="euler")
