"""Voxelise / devoxelise: pure torch ops with known answers."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.pvcnn import (  # noqa: E402
    GroupNorm,
    PVCNNEncoder,
    devoxelize,
    grid_coordinates,
    voxelize,
)


def test_voxelize_averages_points_per_voxel():
    r = 4
    centres = torch.tensor([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
    positions = torch.stack([centres[0], centres[0], centres[1]])[None]  # (1, 3, 3)
    features = torch.tensor([[[1.0, 10.0], [3.0, 30.0], [5.0, 50.0]]])
    volume = voxelize(features, positions, r)  # (1, 2, 4, 4, 4)
    assert volume.shape == (1, 2, r, r, r)
    assert torch.allclose(volume[0, :, 0, 0, 0], torch.tensor([2.0, 20.0]))
    assert torch.allclose(volume[0, :, 3, 3, 3], torch.tensor([5.0, 50.0]))
    assert float(volume.abs().sum()) == pytest.approx(2 + 20 + 5 + 50)


def test_voxelize_keeps_batches_apart():
    positions = torch.zeros(2, 5, 3)
    features = torch.stack([torch.ones(5, 1), 3 * torch.ones(5, 1)])
    volume = voxelize(features, positions, 3)
    assert float(volume[0, 0, 1, 1, 1]) == 1.0 and float(volume[1, 0, 1, 1, 1]) == 3.0


def test_devoxelize_reproduces_linear_fields_exactly():
    r = 5
    g = torch.linspace(-1, 1, r)
    x, y, z = torch.meshgrid(g, g, g, indexing="ij")
    field = torch.stack([2 * x - y + 0.5 * z + 1, x * 0 + 3.0])[None]  # (1, 2, R, R, R)
    p = torch.rand(1, 100, 3, generator=torch.Generator().manual_seed(0)) * 2 - 1
    values = devoxelize(field, p)  # (1, 100, 2)
    expected = 2 * p[..., 0] - p[..., 1] + 0.5 * p[..., 2] + 1
    assert torch.allclose(values[..., 0], expected, atol=1e-5)
    assert torch.allclose(values[..., 1], torch.full_like(expected, 3.0))


def test_devoxelize_hits_voxel_centres_and_clamps_outside():
    r = 4
    volume = torch.randn(2, 3, r, r, r, generator=torch.Generator().manual_seed(1))
    ijk = torch.tensor([[0, 1, 2], [3, 3, 0]])
    p = (ijk.float() / (r - 1) * 2 - 1)[None].expand(2, -1, -1)
    values = devoxelize(volume, p)
    for b in range(2):
        for n, (i, j, k) in enumerate(ijk.tolist()):
            assert torch.allclose(values[b, n], volume[b, :, i, j, k], atol=1e-6)
    outside = devoxelize(volume, torch.full((2, 1, 3), 5.0))
    assert torch.allclose(outside[:, 0], volume[:, :, -1, -1, -1])
    assert float(grid_coordinates(torch.tensor([[-7.0, 0.0, 7.0]]), r).max()) == r - 1


def test_group_norm_matches_torch():
    x = torch.randn(2, 8, 3, 3, 3, generator=torch.Generator().manual_seed(2))
    ours = GroupNorm(groups=4, channels=8)
    ref = torch.nn.GroupNorm(4, 8)
    assert torch.allclose(ours(x), ref(x), atol=1e-5)


def test_encoder_volume_shapes_and_point_count_independence():
    enc = PVCNNEncoder(in_channels=3, stem=8, resolutions=(6, 3), channels=(8, 16))
    for p in (1, 50):
        volumes = enc(torch.rand(3, p, 3) * 2 - 1)
        assert [tuple(v.shape) for v in volumes] == [(3, 8, 6, 6, 6), (3, 16, 3, 3, 3)]
        assert all(np.isfinite(v.detach().numpy()).all() for v in volumes)
