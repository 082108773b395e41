"""A generation's input file: a mesh's surface sampled area-uniformly with face normals,
or a point cloud (:mod:`spacemesh.io.surface`), as ``spacemesh generate`` and the service
read it."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.examples import cube_quads
from spacemesh.io import save_mesh
from spacemesh.io.surface import (
    SURFACE_FORMATS,
    CloudInput,
    input_kind,
    load_cloud_input,
)
from spacemesh.mesh import PolygonMesh


def cube_distance(points: np.ndarray, mesh: PolygonMesh) -> np.ndarray:
    """Distance of points to the surface of an axis-aligned box mesh."""
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    inside = np.minimum(points - lo, hi - points)
    return np.abs(inside).min(axis=1)


@pytest.mark.parametrize("fmt", SURFACE_FORMATS)
def test_every_mesh_format_is_sampled_on_its_surface(tmp_path, fmt):
    cube = cube_quads()
    path = tmp_path / f"cube.{fmt}"
    save_mesh(cube, path)
    cloud = load_cloud_input(path, n_points=600)
    assert cloud.kind == "mesh" and cloud.file_type == fmt
    assert cloud.source == f"{fmt}-surface" and input_kind(cloud.source) == "mesh"
    assert cloud.points.shape == (600, 3) and cloud.normals.shape == (600, 3)
    assert cube_distance(cloud.points, cube).max() < 1e-5
    # each normal is its face's: axis-aligned, pointing out of the box
    assert np.allclose(np.abs(cloud.normals).max(axis=1), 1.0, atol=1e-5)
    centre = cube.vertices.mean(axis=0)
    assert (np.einsum("ij,ij->i", cloud.normals, cloud.points - centre) > 0).all()
    again = load_cloud_input(path.read_bytes(), file_type=fmt, n_points=600)
    assert np.array_equal(again.points, cloud.points)  # seeded: the same file, the same points


def test_sampling_is_area_uniform_and_independent_of_the_vertex_count():
    # a tetrahedron has 4 vertices: read as points it would give 4
    vertices = np.array([[0, 0, 0], [4, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    mesh = PolygonMesh.from_faces(vertices, faces)
    areas = [np.linalg.norm(np.cross(vertices[b] - vertices[a], vertices[c] - vertices[a])) / 2
             for a, b, c in faces]
    data = "".join(f"v {x} {y} {z}\n" for x, y, z in vertices) + "".join(
        "f " + " ".join(str(i + 1) for i in f) + "\n" for f in faces)
    cloud = load_cloud_input(data.encode(), file_type="obj", n_points=20000, seed=1)
    assert len(cloud.points) == 20000
    normals = mesh.face_normals()
    owner = np.argmax(cloud.normals @ normals.T, axis=1)
    share = np.bincount(owner, minlength=4) / 20000
    assert np.allclose(share, np.asarray(areas) / sum(areas), atol=0.02)


@pytest.mark.parametrize("data, fmt", [
    (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
     b"property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n", "ply"),
    (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n", "obj"),
    (b"0 0 0\n1 0 0\n0 1 0\n", "xyz"),
])
def test_files_without_faces_are_point_clouds(data, fmt):
    cloud = load_cloud_input(data, file_type=fmt, n_points=100)
    assert isinstance(cloud, CloudInput) and cloud.kind == "points"
    assert cloud.source == fmt and input_kind(cloud.source) == "points"
    assert len(cloud.points) in (3, 4)


def test_faces_without_area_are_read_as_points():
    data = b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"  # collinear: no surface to sample
    cloud = load_cloud_input(data, file_type="obj", n_points=100)
    assert cloud.kind == "points" and len(cloud.points) == 3


def test_spacemesh_generate_reads_a_mesh_as_its_surface(monkeypatch, tmp_path):
    """The command samples the mesh to the model's point count and says so."""
    import json

    from typer.testing import CliRunner

    from spacemesh.cli import _register
    from spacemesh.cli.common import app
    from spacemesh.runtime import MeshGenerator
    from tests.repair.repair_testing import NoiseBackend, make_spec

    seen = []

    class Recording(NoiseBackend):
        def encode(self, points):
            seen.append(np.asarray(points[0]))
            return super().encode(points)

    def from_repository(cls, path=None, **kwargs):
        return cls(Recording(), make_spec(), name="noise")

    monkeypatch.setattr(MeshGenerator, "from_repository", classmethod(from_repository))
    _register()
    source = tmp_path / "cube.stl"
    save_mesh(cube_quads(), source)
    result = CliRunner().invoke(app, ["generate", str(source), "-o", str(tmp_path / "o.obj"),
                                      "--json", "--no-progress", "--steps", "2"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output.splitlines()[-1])["input"] == "mesh"
    # the encoder saw n_points distinct surface points, not the cube's 8 corners repeated
    assert len(np.unique(seen[0][:, :3], axis=0)) == make_spec().n_points
    points = tmp_path / "cloud.xyz"
    np.savetxt(points, np.random.default_rng(0).normal(size=(300, 3)))
    result = CliRunner().invoke(app, ["generate", str(points), "-o", str(tmp_path / "p.obj"),
                                      "--json", "--no-progress", "--steps", "2"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output.splitlines()[-1])["input"] == "points"
