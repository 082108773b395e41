"""Fitting the stress cases of low-poly models: hubs of degree 40 to 126, needles, n-gons."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")

from spacemesh.decode import DecodeOptions, decode
from spacemesh.encode import encode_connectivity, require_closed_manifold
from spacemesh.examples import icosphere, torus_grid
from spacemesh.fitting import EmbeddingFitConfig, fit_mesh
from spacemesh.fitting.single import hub_step_scale
from spacemesh.fitting.stress import STRESS_CASES, bipyramid, capped_cylinder, pyramid
from spacemesh.mesh import PolygonMesh


@pytest.mark.parametrize("name", sorted(STRESS_CASES))
def test_stress_cases_are_closed_manifolds_with_what_their_names_say(name):
    mesh = STRESS_CASES[name]()
    require_closed_manifold(mesh)
    degree = int(np.diff(encode_connectivity(mesh).offsets).max())
    assert degree >= 30 or int(mesh.face_sizes.max()) >= 30, name


@pytest.mark.parametrize(
    ("make", "budget"),
    [
        (lambda: pyramid(40), 60),  # a degree-40 fan over a 40-gon
        (lambda: bipyramid(40, height=20.0), 60),  # needle triangles
        # two hubs of degree 126 without a common neighbour (a CAD boss): 68 iterations
        # with plain Adam, 26 with the hubs' longer steps
        (lambda: capped_cylinder(126), 45),
    ],
)
def test_high_degree_meshes_fit_exactly_within_budget(make, budget):
    mesh = make()
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=budget, threads=1))
    assert result.exact, result.summary()
    assert result.decoded.mesh.face_key_set() == mesh.face_key_set()


def test_hub_steps_scale_only_hubs():
    for mesh in (icosphere(2), torus_grid(8, 5, 3)):  # no hubs: plain Adam, bit for bit
        degrees = np.diff(encode_connectivity(mesh).offsets)
        assert np.all(hub_step_scale(degrees, 0.5) == 1.0)
    degrees = np.diff(encode_connectivity(capped_cylinder(126)).offsets)
    scale = hub_step_scale(degrees, 0.5)
    assert np.all(scale[degrees == 126] > 5.0) and np.all(scale[degrees < 126] == 1.0)
    assert np.all(hub_step_scale(degrees, 0.0) == 1.0)


def test_fit_judges_the_embeddings_not_the_generators_geometric_clean_up():
    """A tetrahedron folded nearly flat: its edges 0-1 and 2-3 cross geometrically.

    The generator's decode drops the weaker of two crossing quad diagonals
    (``DecodeOptions.uncross``), so no embedding could ever decode to this mesh with it
    on; low-poly models (issue 20's, and two of ../shared/meshes) have such folds.
    """
    v = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, -0.1, 0.01]])
    mesh = PolygonMesh.from_faces(v, [[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]])
    require_closed_manifold(mesh)
    result = fit_mesh(mesh, EmbeddingFitConfig(max_iters=100, threads=1))
    assert result.exact, result.summary()
    assert result.decoded.n_uncrossed == 0
    generator = decode(mesh.vertices, result.embeddings, DecodeOptions(max_degree=None))
    assert generator.n_uncrossed == 1 and generator.mesh.face_key_set() != mesh.face_key_set()
