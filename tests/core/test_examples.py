import numpy as np
import pytest

from spacemesh.examples import EXAMPLES
from spacemesh.primitives import triangulate_faces
from spacemesh.topology import check_topology


@pytest.mark.parametrize("name", EXAMPLES)
def test_examples_are_closed_outward_manifolds(name):
    mesh = EXAMPLES[name]()
    assert check_topology(mesh).is_closed_oriented_manifold
    v = mesh.vertices
    tri, _ = triangulate_faces(mesh)
    volume = np.einsum("ij,ij->i", v[tri[:, 0]], np.cross(v[tri[:, 1]], v[tri[:, 2]])).sum() / 6
    assert volume > 0
