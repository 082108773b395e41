"""The shipped default model behind the real server (skipped until models/ has it)."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from spacemesh.examples import torus_grid
from spacemesh.io import load_mesh
from spacemesh.primitives import sample_surface
from spacemesh.runtime import default_model_dir
from spacemesh.runtime.repository import MANIFEST, resolve_version_dir
from spacemesh.topology import check_topology

pytestmark = pytest.mark.slow


def _shipped() -> bool:
    try:
        return (resolve_version_dir(default_model_dir()) / MANIFEST).is_file()
    except Exception:
        return False


@pytest.mark.skipif(not _shipped(), reason="no shipped model under models/ yet")
def test_generate_on_2048_points_gives_an_oriented_manifold(start_server):
    server = start_server(model=None, ort_threads=0, max_points=200_000)  # the default model
    points, _ = sample_surface(torus_grid(48, 24), 2048, np.random.default_rng(0))
    points = points * 2.5 + np.array([1.0, 2.0, -3.0])  # any frame and scale
    statuses = []
    for seed in range(3):
        response = httpx.post(server.url + "/generate", timeout=120,
                              json={"points": points.tolist(), "seed": seed, "format": "ply"})
        statuses.append(response.status_code)
        if response.status_code != 200:
            assert response.json()["type"].endswith("/no-surface"), response.text
            continue
        mesh = load_mesh(response.content, file_type="ply")
        report = check_topology(mesh)
        assert report.is_closed_oriented_manifold, report.defects()
        assert response.headers["x-spacemesh-oriented"] == "true"
        lo, hi = points.min(axis=0), points.max(axis=0)
        assert np.all(mesh.vertices > lo - (hi - lo)) and np.all(mesh.vertices < hi + (hi - lo))
        if 200 in statuses[:-1]:
            continue  # the GLB of one mesh is enough
        # the triangulated GLB of the same mesh is a closed oriented manifold too
        glb = httpx.post(server.url + "/generate", timeout=120,
                         json={"points": points.tolist(), "seed": seed, "format": "glb"})
        triangles = load_mesh(glb.content, file_type="glb")
        assert triangles.n_faces == int((mesh.face_sizes - 2).sum()) + 2 * (
            triangles.n_vertices - mesh.n_vertices)
        glb_report = check_topology(triangles)
        assert glb_report.is_closed_oriented_manifold, glb_report.defects()
    assert 200 in statuses, statuses
