"""The local-point denoiser: nearest-point features, the attention, and the config flag."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.config import SMALL, TINY, get_config  # noqa: E402
from spacemesh.nn.geometry import OFFSET_SCALE  # noqa: E402
from spacemesh.nn.local_points import nearest_points  # noqa: E402
from spacemesh.nn.model import model_from_config  # noqa: E402


def test_nearest_points_are_the_brute_force_nearest_with_offsets_and_normals():
    rng = np.random.default_rng(0)
    positions = rng.uniform(-1.2, 1.2, (2, 7, 3)).astype(np.float32)
    cloud = rng.uniform(-1, 1, (2, 40, 6)).astype(np.float32)
    out = nearest_points(torch.from_numpy(positions), torch.from_numpy(cloud), 5).numpy()
    assert out.shape == (2, 7, 5, 7)
    for b in range(2):
        for i in range(7):
            d2 = ((cloud[b, :, :3] - positions[b, i]) ** 2).sum(1)
            order = np.argsort(d2)[:5]
            offsets = (cloud[b, order, :3] - positions[b, i]) * OFFSET_SCALE
            assert np.allclose(out[b, i, :, :3], offsets, atol=1e-5)
            assert np.allclose(out[b, i, :, 3], d2[order] * OFFSET_SCALE**2, atol=1e-4)
            assert np.allclose(out[b, i, :, 4:], cloud[b, order, 3:])
    # without normals: offsets and squared lengths only
    assert nearest_points(torch.from_numpy(positions), torch.from_numpy(cloud[..., :3]),
                          5).shape == (2, 7, 5, 4)


def test_local_denoiser_is_permutation_equivariant_and_reads_the_points():
    torch.manual_seed(0)
    model = model_from_config("tiny-local").eval()
    points = torch.rand(2, 256, 3) * 2 - 1
    x_t, t = torch.randn(2, 64, 4), torch.tensor([3, 40])
    with torch.no_grad():
        volumes = model.encoder(points)
        eps = model.denoiser(x_t, t, volumes, points)
        order, shuffle = torch.randperm(64), torch.randperm(256)
        permuted = model.denoiser(x_t[:, order], t, volumes, points[:, shuffle])
        moved = model.denoiser(x_t, t, volumes, points * 0.9)
    assert torch.allclose(permuted, eps[:, order], atol=1e-5)
    assert not torch.allclose(moved, eps, atol=1e-4)  # the points themselves matter
    with pytest.raises(ValueError, match="pass points"):
        model.denoiser(x_t, t, volumes)


def test_the_flag_is_off_in_the_existing_configs():
    for config in (TINY, SMALL, get_config("paper")):
        assert config.denoiser.local_points == 0 and not config.train.diffusion_only
    keys = model_from_config("small").denoiser.state_dict()
    assert not any(k.startswith(("local_attention", "neighbour_features")) for k in keys)
    local = model_from_config("small-local").denoiser.state_dict()
    assert sum(k.startswith("local_attention.") for k in local) > 0
