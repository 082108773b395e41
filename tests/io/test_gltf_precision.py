"""GLB and glTF keep float64 precision far from the origin: the positions are float32
relative to the node's float64 translation, and every reader applies it."""

from __future__ import annotations

import io
import json
import struct

import numpy as np
import pytest

from spacemesh.examples import icosphere, torus_grid
from spacemesh.io import export_mesh, load_mesh
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_manifold
from spacemesh.topology import check_topology

#: Where the test meshes sit: about 1e6 from the origin, with float64 fractions.
FAR = np.array([1_000_000.123456789, -999_999.87654321, 1_000_000.5])
#: Their size (bounding box diagonal) is about this.
SIZE = 10.0


def far_meshes() -> dict[str, PolygonMesh]:
    """An icosphere (triangles) and a torus (quads) of size ~10 near (1e6, -1e6, 1e6),
    rotated so that no coordinate is a float32."""
    rotation = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))[0]
    meshes = {}
    for name, mesh in {"icosphere": icosphere(2), "torus": torus_grid(16, 8)}.items():
        local = mesh.vertices - mesh.vertices.mean(axis=0)
        local *= SIZE / np.linalg.norm(np.ptp(local, axis=0))
        meshes[name] = PolygonMesh(local @ rotation.T + FAR, mesh.face_indices,
                                   mesh.face_offsets)
    return meshes


def _expected(mesh: PolygonMesh) -> np.ndarray:
    """The written vertices (the triangulation may append centroid vertices)."""
    return triangulate_manifold(mesh)[0]


def _relative_error(got: np.ndarray, mesh: PolygonMesh) -> float:
    expected = _expected(mesh)
    assert got.shape == expected.shape
    return float(np.abs(got - expected).max() / np.linalg.norm(np.ptp(expected, axis=0)))


def _glb_document(data: bytes) -> dict:
    json_length, _ = struct.unpack_from("<II", data, 12)
    return json.loads(data[20:20 + json_length])


@pytest.mark.parametrize("name", ["icosphere", "torus"])
def test_float32_alone_would_lose_the_shape(name):
    """The inputs really do stress float32: stored absolute, they move by >1e-3 of their
    size (1/16 unit steps at 1e6), so the tests below could fail."""
    mesh = far_meshes()[name]
    naive = _expected(mesh).astype(np.float32).astype(np.float64)
    assert _relative_error(naive, mesh) > 1e-3


@pytest.mark.parametrize("fmt", ["glb", "gltf"])
@pytest.mark.parametrize("name", ["icosphere", "torus"])
def test_far_meshes_round_trip_through_our_reader(name, fmt):
    mesh = far_meshes()[name]
    data = export_mesh(mesh, fmt)
    back = load_mesh(data, file_type=fmt)
    assert _relative_error(back.vertices, mesh) < 1e-6
    report = check_topology(back)
    assert back.n_faces > 0 and report.is_closed_oriented_manifold, report.defects()
    doc = _glb_document(data) if fmt == "glb" else json.loads(data)
    node = doc["nodes"][0]
    expected = _expected(mesh)
    assert np.allclose(node["translation"], (expected.min(0) + expected.max(0)) / 2, rtol=0,
                       atol=1e-9)
    position = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    assert np.all(np.abs(position["min"]) < SIZE) and np.all(np.abs(position["max"]) < SIZE)


@pytest.mark.parametrize("name", ["icosphere", "torus"])
def test_far_meshes_round_trip_through_trimesh(name):
    trimesh = pytest.importorskip("trimesh")
    mesh = far_meshes()[name]
    loaded = trimesh.load(io.BytesIO(export_mesh(mesh, "glb")), file_type="glb",
                          force="mesh", process=False)
    assert _relative_error(np.asarray(loaded.vertices, dtype=np.float64), mesh) < 1e-6


@pytest.mark.parametrize("fmt", ["glb", "gltf"])
def test_far_meshes_round_trip_through_the_client(fmt):
    formats = pytest.importorskip("spacemesh_client._formats")
    mesh = far_meshes()["torus"]
    vertices, faces = formats.read_mesh(export_mesh(mesh, fmt), fmt)
    assert _relative_error(np.asarray(vertices), mesh) < 1e-6
    # and what the client writes, our reader reads back as precisely
    written = formats.write_mesh(vertices, faces, fmt)
    again = load_mesh(written, file_type=fmt)
    assert np.abs(again.vertices - vertices).max() < 1e-6 * SIZE


def test_meshes_that_float32_holds_exactly_keep_their_plain_node():
    mesh = icosphere(1)
    exact = PolygonMesh(np.round(mesh.vertices * 1024) / 1024 + 3.0,  # float32 holds them
                        mesh.face_indices, mesh.face_offsets)
    data = export_mesh(exact, "glb")
    assert _glb_document(data)["nodes"] == [{"mesh": 0}]
    assert np.array_equal(load_mesh(data, file_type="glb").vertices, _expected(exact))
