"""Point clouds: every format, format sniffing, bytes input and malformed files."""

from __future__ import annotations

import io

import numpy as np
import pytest

from spacemesh.io import export_mesh, load_points
from spacemesh.io.errors import MeshFormatError, UnsupportedFormatError
from spacemesh.io.points import SUPPORTED_POINTS_READ
from spacemesh.mesh import PolygonMesh

RNG = np.random.default_rng(7)
POINTS = RNG.normal(size=(50, 3))
NORMALS = POINTS / np.linalg.norm(POINTS, axis=1, keepdims=True)


def ply_points(normals: bool, faces: bool = False, encoding: str = "binary_little_endian") -> bytes:
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals else [])
    header = ["ply", f"format {encoding} 1.0", f"element vertex {len(POINTS)}"]
    header += [f"property double {p}" for p in props]
    table = np.hstack([POINTS, NORMALS]) if normals else POINTS
    if faces:
        header += ["element face 1", "property list uchar int vertex_indices"]
    header.append("end_header")
    head = ("\n".join(header) + "\n").encode()
    if encoding == "ascii":
        body = "".join(" ".join(repr(v) for v in row) + "\n" for row in table.tolist())
        body += "3 0 1 2\n" if faces else ""
        return head + body.encode()
    order = "<" if encoding == "binary_little_endian" else ">"
    body = table.astype(order + "f8").tobytes()
    if faces:
        body += b"\x03" + np.array([0, 1, 2], dtype=order + "i4").tobytes()
    return head + body


def npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def npz_bytes(**arrays: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def text_columns(table: np.ndarray, sep: str = " ") -> bytes:
    return "".join(sep.join(repr(v) for v in row) + "\n" for row in table.tolist()).encode()


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("faces", [False, True])
def test_ply(encoding, faces):
    points, normals = load_points(ply_points(True, faces, encoding), file_type="ply")
    assert np.array_equal(points, POINTS) and np.array_equal(normals, NORMALS)
    points, normals = load_points(ply_points(False, faces, encoding))  # sniffed
    assert np.array_equal(points, POINTS) and normals is None


def test_ply_written_by_the_mesh_writer():
    mesh = PolygonMesh.from_faces(POINTS[:4], [[0, 1, 2, 3]])
    points, normals = load_points(export_mesh(mesh, "ply"), file_type="ply")
    assert np.array_equal(points, POINTS[:4]) and normals is None


@pytest.mark.parametrize("sep", [" ", ",", "\t", ", "])
@pytest.mark.parametrize("fmt", ["xyz", "txt", "pts", "csv"])
def test_text_columns(sep, fmt):
    points, normals = load_points(text_columns(POINTS, sep), file_type=fmt)
    assert np.array_equal(points, POINTS) and normals is None
    points, normals = load_points(text_columns(np.hstack([POINTS, NORMALS]), sep), file_type=fmt)
    assert np.array_equal(points, POINTS) and np.array_equal(normals, NORMALS)


def test_text_comments_count_line_and_header():
    data = b"# scan 1\n3\n0 0 0\n1 0 0 # first axis\n\n0 1 0\n"
    points, _ = load_points(data, file_type="pts")
    assert points.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    points, normals = load_points(b"x,y,z,nx,ny,nz\n1,2,3,0,0,1\n4,5,6,0,1,0\n", file_type="csv")
    assert points.tolist() == [[1, 2, 3], [4, 5, 6]] and normals.tolist() == [[0, 0, 1], [0, 1, 0]]


def test_six_columns_of_colours_are_not_normals():
    points, normals = load_points(b"0 0 0 255 0 0\n1 0 0 0 255 0\n", file_type="xyz")
    assert len(points) == 2 and normals is None


def test_numpy_files():
    points, normals = load_points(npy_bytes(POINTS), file_type="npy")
    assert np.array_equal(points, POINTS) and normals is None
    points, normals = load_points(npy_bytes(np.hstack([POINTS, NORMALS]).astype(np.float32)))
    assert np.allclose(points, POINTS, atol=1e-6) and normals is not None
    points, normals = load_points(npz_bytes(points=POINTS, normals=NORMALS), file_type="npz")
    assert np.array_equal(points, POINTS) and np.array_equal(normals, NORMALS)
    points, normals = load_points(npz_bytes(cloud=POINTS))  # a single array, sniffed
    assert np.array_equal(points, POINTS) and normals is None


def test_obj_vertices_and_normals():
    rows = [f"v {x!r} {y!r} {z!r}" for x, y, z in POINTS.tolist()]
    normals_rows = [f"vn {x!r} {y!r} {z!r}" for x, y, z in NORMALS.tolist()]
    points, normals = load_points(("\n".join(rows + normals_rows) + "\n").encode())
    assert np.array_equal(points, POINTS) and np.array_equal(normals, NORMALS)
    points, normals = load_points(("\n".join([*rows, normals_rows[0]]) + "\n").encode(), "obj")
    assert np.array_equal(points, POINTS) and normals is None


def test_mesh_formats_give_their_vertices():
    mesh = PolygonMesh.from_faces(POINTS[:4], [[0, 1, 2], [0, 2, 3]])
    for fmt in ("off", "stl", "glb", "gltf"):
        points, normals = load_points(export_mesh(mesh, fmt), file_type=fmt)
        assert len(points) == 4 and normals is None


def test_paths_and_extensions(tmp_path):
    (tmp_path / "cloud.XYZ").write_bytes(text_columns(POINTS))
    (tmp_path / "cloud.npy").write_bytes(npy_bytes(POINTS))
    (tmp_path / "cloud").write_bytes(ply_points(True))  # no extension: sniffed
    for name in ("cloud.XYZ", "cloud.npy", "cloud"):
        points, _ = load_points(tmp_path / name)
        assert np.array_equal(points, POINTS)
        points, _ = load_points(str(tmp_path / name))
        assert np.array_equal(points, POINTS)
    # The extension wins over the content; a file name can be the file type.
    with pytest.raises(MeshFormatError):
        load_points(ply_points(True), file_type="scan.npy")
    points, _ = load_points(text_columns(POINTS), file_type="upload.txt")
    assert np.array_equal(points, POINTS)


def test_supported_types():
    assert {"ply", "xyz", "pts", "txt", "npy", "npz", "las", "laz", "obj"} <= set(
        SUPPORTED_POINTS_READ)
    with pytest.raises(UnsupportedFormatError, match=r"\.xyz"):
        load_points(text_columns(POINTS), file_type="e57")


MALFORMED = {
    "empty": ("xyz", b""),
    "blank": ("ply", b"\n \n"),
    "ragged": ("xyz", b"0 0 0\n1 0\n"),
    "two columns": ("xyz", b"0 0\n1 0\n"),
    "word": ("xyz", b"0 0 0\n1 zero 0\n"),
    "nan": ("xyz", b"0 0 0\nnan 1 2\n"),
    "nan normal": ("xyz", b"0 0 0 0 0 1\n1 1 1 nan 0 1\n"),
    "only comments": ("pts", b"# nothing here\n"),
    "npy shape": ("npy", npy_bytes(np.zeros((4, 2)))),
    "npy strings": ("npy", npy_bytes(np.array([["a", "b", "c"]]))),
    "npy garbage": ("npy", b"\x93NUMPY garbage"),
    "npy object": ("npy", npy_bytes(np.array([[1, 2, 3]], dtype=object))),
    "npz wrong keys": ("npz", npz_bytes(a=POINTS, b=POINTS)),
    "npz normals mismatch": ("npz", npz_bytes(points=POINTS, normals=NORMALS[:3])),
    "npz garbage": ("npz", b"PK\x03\x04 garbage"),
    "las garbage": ("las", b"LASF" + b"\x00" * 300),
    "laz not las": ("laz", b"\x00\xff\x13\x37" * 80),
    "ply truncated": ("ply", ply_points(True)[:-100]),
    "obj no vertices": ("obj", b"vn 0 0 1\n"),
    "garbage bytes": ("ply", b"\x00\xff\x13\x37" * 20),
    "binary as text": ("xyz", b"\x00\xff\x13\x37" * 20),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_point_files(case):
    fmt, data = MALFORMED[case]
    with pytest.raises(MeshFormatError, match=r"\S"):
        load_points(data, file_type=fmt)


def test_unrecognisable_bytes():
    with pytest.raises(UnsupportedFormatError):
        load_points(b"\x01\x02\x03 not a point cloud \x04")
    with pytest.raises(MeshFormatError):
        load_points(b"")
