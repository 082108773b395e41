"""The three networks: configs as data, equivariance, masking, and the padded loss."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.config import (  # noqa: E402
    CONFIGS,
    ModelConfig,
    get_config,
)
from spacemesh.nn.losses import (  # noqa: E402
    PermutationReduction,
    degree_groups,
    permutation_loss,
)
from spacemesh.nn.model import (  # noqa: E402
    NeighbourTable,
    model_from_config,
    padded_permutation_loss,
)
from spacemesh.train.batching import concat_connectivity  # noqa: E402


@pytest.fixture(scope="module")
def tiny():
    torch.manual_seed(0)
    return model_from_config("tiny").eval()


def test_configs_round_trip_through_dicts():
    for config in CONFIGS.values():
        assert ModelConfig.from_dict(config.to_dict()) == config
    paper = get_config("paper")
    assert (paper.connectivity.adjacency_dim, paper.connectivity.permutation_dim) == (32, 12)
    assert paper.denoiser.width == 256 and paper.denoiser.layers == 10
    assert paper.encoder.resolutions == (32, 16, 8) and paper.encoder.channels == (64, 128, 256)
    assert paper.diffusion.timesteps == 1024
    with pytest.raises(ValueError):
        get_config("huge")
    with pytest.raises(ValueError):
        ModelConfig.from_dict({**CONFIGS["tiny"].to_dict(), "encoder": {"bogus": 1}})


def test_factory_accepts_names_dicts_and_configs():
    a = model_from_config("tiny")
    b = model_from_config(get_config("tiny").to_dict())
    assert sum(p.numel() for p in a.parameters()) == sum(p.numel() for p in b.parameters())


def _inputs(model, b=2, n=20, seed=0):
    g = torch.Generator().manual_seed(seed)
    points = torch.rand(b, 64, 3, generator=g) * 2 - 1
    with torch.no_grad():
        volumes = model.encoder(points)
    vertices = torch.rand(b, n, 3, generator=g) * 2 - 1
    return volumes, vertices


def test_networks_are_permutation_equivariant(tiny):
    volumes, vertices = _inputs(tiny)
    perm = torch.randperm(vertices.shape[1], generator=torch.Generator().manual_seed(3))
    valid = torch.ones(vertices.shape[:2], dtype=torch.bool)
    with torch.no_grad():
        a = tiny.connectivity(vertices, valid, volumes)
        b = tiny.connectivity(vertices[:, perm], valid[:, perm], volumes)
        for x, y in zip(a[:4], b[:4], strict=True):
            assert torch.allclose(x[:, perm], y, atol=1e-5)
        x_t = torch.cat([vertices, torch.ones_like(vertices[..., :1])], -1)
        t = torch.tensor([5, 40])
        e1 = tiny.denoiser(x_t, t, volumes)
        e2 = tiny.denoiser(x_t[:, perm], t, volumes)
        assert torch.allclose(e1[:, perm], e2, atol=1e-5)


def test_padding_does_not_change_real_vertices(tiny):
    volumes, vertices = _inputs(tiny, n=12)
    valid = torch.ones(2, 12, dtype=torch.bool)
    junk = torch.rand(2, 5, 3) * 2 - 1
    padded = torch.cat([vertices, junk], 1)
    padded_valid = torch.cat([valid, torch.zeros(2, 5, dtype=torch.bool)], 1)
    with torch.no_grad():
        a = tiny.connectivity(vertices, valid, volumes)
        b = tiny.connectivity(padded, padded_valid, volumes)
    for x, y in zip(a[:4], b[:4], strict=True):
        assert torch.allclose(x, y[:, :12], atol=1e-5)
    assert a[4].shape == (1,)


def test_output_sizes_follow_the_config(tiny):
    volumes, vertices = _inputs(tiny)
    x, root, prev, nxt, _tau = tiny.connectivity(vertices, torch.ones(2, 20, dtype=torch.bool),
                                                volumes)
    con = tiny.config.connectivity
    assert x.shape == (2, 20, con.adjacency_dim)
    assert root.shape == prev.shape == nxt.shape == (2, 20, con.permutation_dim)


@pytest.mark.parametrize("kind", ["product", "concat"])
def test_padded_permutation_loss_equals_the_reference(kind):
    from spacemesh.encode import encode_connectivity
    from tests.factories import prism, torus_grid

    conns = [encode_connectivity(m) for m in (torus_grid(6, 5, triangulate_every=3), prism(7))]
    n = max(c.n_vertices for c in conns) + 3
    graph = concat_connectivity(conns, n)
    g = torch.Generator().manual_seed(4)
    root, prev, nxt = (torch.randn(2 * n, 6, generator=g, dtype=torch.float64) for _ in range(3))
    reduction = PermutationReduction(kind, dim=6).double()
    ref, ref_correct = permutation_loss(degree_groups(graph), root, prev, nxt, reduction)
    ours, correct = padded_permutation_loss(
        NeighbourTable.from_connectivity(graph, buckets=(3, 4)), root, prev, nxt, reduction
    )
    assert float(ours.detach()) == pytest.approx(float(ref.detach()), rel=1e-4)
    assert int(correct) == int(ref_correct)
