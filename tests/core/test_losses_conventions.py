"""The torch losses and the numpy decode follow one convention."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.encode import encode_connectivity  # noqa: E402
from spacemesh.nn.losses import (  # noqa: E402
    PermutationReduction,
    degree_groups,
    dense_distance,
    edge_loss_dense,
    edge_loss_pairs,
    group_log_phi_bar,
    permutation_loss,
)
from spacemesh.permutation import neighbourhood_log_phi_bar, reduction_logits  # noqa: E402
from spacemesh.spacetime import pairwise_distance  # noqa: E402
from tests.factories import icosphere, torus_grid  # noqa: E402


@pytest.mark.parametrize("distance", ["spacetime", "euclidean", "dot"])
def test_distances_agree(distance):
    x = np.random.default_rng(0).normal(size=(40, 8))
    d_np = pairwise_distance(x, distance=distance)
    d_t = dense_distance(torch.as_tensor(x), distance).numpy()
    np.testing.assert_allclose(d_np, d_t, atol=1e-9)


@pytest.mark.parametrize("kind", ["product", "sum", "max", "concat"])
def test_reductions_agree(kind):
    torch.manual_seed(0)
    module = PermutationReduction(kind, dim=5).double()
    rng = np.random.default_rng(1)
    root, prev, nxt = (
        rng.normal(size=(3, 5)),
        rng.normal(size=(3, 4, 5)),
        rng.normal(size=(3, 4, 5)),
    )
    expected = reduction_logits(root, prev, nxt, kind, module.numpy_params())
    got = module(*(torch.as_tensor(a) for a in (root, prev, nxt))).detach().numpy()
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_phi_bar_and_permutation_loss_agree_with_numpy():
    mesh = torus_grid(8, 6, triangulate_every=2)
    conn = encode_connectivity(mesh)
    rng = np.random.default_rng(2)
    n = mesh.n_vertices
    root, prev, nxt = (rng.normal(size=(n, 6)) for _ in range(3))
    reduction = PermutationReduction("product").double()
    tensors = [torch.as_tensor(a) for a in (root, prev, nxt)]
    manual = []
    for group in degree_groups(conn):
        log_t = group_log_phi_bar(group, *tensors, reduction).numpy()
        log_np = neighbourhood_log_phi_bar(
            root, prev, nxt, group.vertices.numpy(), conn.offsets, conn.neighbours, group.degree
        )
        np.testing.assert_allclose(log_t, log_np, atol=1e-9)
        manual.append(-np.take_along_axis(log_np, group.target.numpy()[..., None], 2).ravel())
    loss, _ = permutation_loss(degree_groups(conn), *tensors, reduction)
    assert float(loss) == pytest.approx(np.concatenate(manual).mean())


def test_edge_loss_is_eq3_with_lambda():
    mesh = icosphere(1)
    conn = encode_connectivity(mesh)
    n, edges = mesh.n_vertices, conn.edges
    rng = np.random.default_rng(3)
    x = rng.normal(size=(n, 16))
    tau = 0.3
    d = pairwise_distance(x)
    adj = np.zeros((n, n), bool)
    adj[edges[:, 0], edges[:, 1]] = True
    iu = np.triu_indices(n, 1)
    pos, neg = adj[iu], ~adj[iu]
    softplus = np.logaddexp(0, d[iu] - tau)  # -log sigmoid(tau - d)
    softplus_neg = np.logaddexp(0, tau - d[iu])
    lam = 4 * len(edges) / n**2
    expected = (softplus[pos].sum() + lam * softplus_neg[neg].sum()) / len(edges)
    xt = torch.as_tensor(x)
    got = edge_loss_dense(
        xt[None], torch.tensor(tau, dtype=torch.float64), torch.as_tensor(adj)[None]
    )
    assert float(got) == pytest.approx(expected, rel=1e-9)
    # the pair form with all negatives at weight 1 is the same number
    negatives = torch.as_tensor(np.stack(iu, 1)[neg])
    got_pairs = edge_loss_pairs(
        xt,
        torch.tensor(tau, dtype=torch.float64),
        torch.as_tensor(edges),
        negatives,
        torch.ones(len(negatives), dtype=torch.float64),
        lam,
    )
    assert float(got_pairs) == pytest.approx(expected, rel=1e-9)
    # and an edge is d < tau in both worlds
    assert np.array_equal(d[iu] < tau, (dense_distance(xt)[iu] < tau).numpy())


@pytest.mark.parametrize("form", ["dense", "pairs"])
def test_false_positive_margin_keeps_the_weight_just_above_the_threshold(form):
    """A non-edge just out (tau < d < tau + margin) keeps the false-positive weight."""
    x = torch.tensor([[0.0, 0.0], [1.0, 0.0], [0.0, 1.05]], dtype=torch.float64,
                     requires_grad=True)
    tau = torch.tensor(1.0, dtype=torch.float64)  # squared euclidean: d01 = 1, d02 = 1.1025
    edges = torch.tensor([[0, 1]])

    def grad_on_vertex_2(margin: float) -> float:
        x.grad = None
        if form == "dense":
            adj = torch.zeros(1, 3, 3, dtype=torch.bool)
            adj[0, 0, 1] = adj[0, 1, 0] = True
            loss = edge_loss_dense(x[None], tau, adj, None, "euclidean", None, 1.0, margin)
        else:
            negatives = torch.tensor([[0, 2], [1, 2]])
            loss = edge_loss_pairs(x, tau, edges, negatives, torch.ones(2, dtype=torch.float64),
                                   4 / 9, "euclidean", None, 1.0, margin)
        loss.backward()
        return float(x.grad[2].norm())

    without, within = grad_on_vertex_2(0.0), grad_on_vertex_2(0.5)
    assert within > 1.5 * without  # weight 1 instead of lambda = 4/9
    assert grad_on_vertex_2(0.05) == pytest.approx(without)  # beyond the margin: lambda again
