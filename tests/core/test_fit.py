import pytest

pytest.importorskip("torch")

from spacemesh.decode import decode
from spacemesh.fitting import EmbeddingFitConfig, fit_mesh
from spacemesh.halfedge import HalfedgeMesh
from tests.factories import cube_quads, icosphere, prism, torus_grid


@pytest.mark.parametrize(
    "make", [lambda: icosphere(1), cube_quads, lambda: prism(6), lambda: torus_grid(8, 5, 3)]
)
def test_fit_recovers_mesh_exactly(make):
    mesh = make()
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=400, threads=1))
    assert result.exact, result.summary()
    assert result.edge_f1 == 1.0 and result.next_accuracy == 1.0
    assert result.decoded.mesh.face_key_set() == mesh.face_key_set()
    # the stored embeddings decode to the same mesh again
    again = decode(mesh.vertices, result.embeddings)
    assert again.mesh.face_key_set() == mesh.face_key_set()
    assert HalfedgeMesh.from_connectivity(again.connectivity).is_valid()


def test_sparse_mode_recovers_mesh():
    """The mined-negative edge loss (used above dense_limit) also gets exact."""
    mesh = icosphere(2)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=600, dense_limit=10, threads=1))
    assert result.exact, result.summary()


def test_budget_exhausted_reports_not_exact():
    result = fit_mesh(icosphere(2), EmbeddingFitConfig(max_iters=2, threads=1))
    assert not result.exact
    assert result.iterations == 2
    assert 0.0 <= result.edge_f1 < 1.0


def test_paper_loss_alone_also_recovers():
    """Eq. 3 exactly (no false-positive weighting) still fits a small mesh."""
    config = EmbeddingFitConfig(max_iters=400, threads=1, false_positive_weight=None)
    result = fit_mesh(icosphere(1), config)
    assert result.exact, result.summary()


def test_high_degree_poles_are_recovered():
    """A bicone whose two apexes have degree 80, above the decode's default degree bound."""
    import numpy as np

    from spacemesh.mesh import PolygonMesh

    n = 80
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.c_[np.cos(a), np.sin(a), np.zeros(n)]
    v = np.vstack([ring, [[0, 0, 1], [0, 0, -1]]])
    top, bottom = n, n + 1
    faces = [[i, (i + 1) % n, top] for i in range(n)] + [[(i + 1) % n, i, bottom] for i in range(n)]
    mesh = PolygonMesh.from_faces(v, faces)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=600, threads=1))
    assert result.exact, result.summary()


@pytest.mark.parametrize("dense_limit", [1024, 10])
def test_positions_init_recovers_mesh(dense_limit):
    """Starting from the vertex positions also converges, in dense and sparse mode."""
    mesh = icosphere(2)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=400, init="positions",
                                               dense_limit=dense_limit,
                                               threads=1))
    assert result.exact, result.summary()


def test_bad_init_is_a_value_error():
    with pytest.raises(ValueError, match="unknown init"):
        fit_mesh(icosphere(1), EmbeddingFitConfig(init="spectral"))
    with pytest.raises(ValueError, match="space coordinates"):
        fit_mesh(icosphere(1), EmbeddingFitConfig(init="positions", distance="dot"))
