"""Mesh files: round trips of every format, format variants, and malformed input."""

from __future__ import annotations

import base64
import io
import json
import struct

import numpy as np
import pytest

from spacemesh.io import (
    SUPPORTED_MESH_READ,
    SUPPORTED_MESH_WRITE,
    export_mesh,
    load_mesh,
    save_mesh,
    sniff_file_type,
)
from spacemesh.io.errors import MeshFormatError, UnsupportedFormatError
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_faces
from spacemesh.topology import check_topology


# ---------------------------------------------------------------------- test meshes
def cube() -> PolygonMesh:
    """The unit cube as six outward quads."""
    v = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        dtype=np.float64,
    )
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    return PolygonMesh.from_faces(v * 0.1 + np.array([0.3, -0.7, 1.1]), faces)


def sphere() -> PolygonMesh:
    """An icosphere (one subdivision, 80 outward triangles)."""
    t = (1 + 5**0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t]]
    v += [[0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    faces = [
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
        [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
        [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ]  # fmt: skip
    vertices = [np.array(p, dtype=np.float64) for p in v]
    midpoint: dict[tuple[int, int], int] = {}

    def middle(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in midpoint:
            midpoint[key] = len(vertices)
            vertices.append((vertices[a] + vertices[b]) / 2)
        return midpoint[key]

    fine = []
    for a, b, c in faces:
        ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
        fine += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    points = np.array(vertices)
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    return PolygonMesh.from_faces(points * 2.5, fine)


def prism(outline: np.ndarray, height: float = 1.0) -> PolygonMesh:
    """A closed prism over a counter-clockwise outline (bottom, top, side quads)."""
    n = len(outline)
    bottom = np.column_stack([outline, np.zeros(n)])
    top = np.column_stack([outline, np.full(n, height)])
    faces = [list(range(n))[::-1], list(range(n, 2 * n))]
    faces += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return PolygonMesh.from_faces(np.vstack([bottom, top]), faces)


def l_prism() -> PolygonMesh:
    """A prism whose caps are the non-convex L-shaped hexagon."""
    outline = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=np.float64)
    return prism(outline, height=0.5)


def pentagon_prism() -> PolygonMesh:
    """A prism over a regular pentagon."""
    angles = np.linspace(0, 2 * np.pi, 6)[:5]
    return prism(np.column_stack([np.cos(angles), np.sin(angles)]), height=1.5)


MESHES = {"cube": cube, "sphere": sphere, "l_prism": l_prism, "pentagon_prism": pentagon_prism}
POLYGON_FORMATS = [
    ("obj", {}),
    ("off", {}),
    ("ply", {}),
    ("ply", {"encoding": "ascii"}),
    ("ply", {"encoding": "binary_little_endian"}),
    ("ply", {"encoding": "binary_big_endian"}),
]


def signed_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


def newell_normals(mesh: PolygonMesh) -> np.ndarray:
    return mesh.face_normals()


def test_test_meshes_are_closed_oriented_manifolds():
    for make in MESHES.values():
        mesh = make()
        assert check_topology(mesh).is_closed_oriented_manifold
        assert signed_volume(mesh.vertices, triangulate_faces(mesh)[0]) > 0


# ---------------------------------------------------------------------- round trips
@pytest.mark.parametrize("name", sorted(MESHES))
@pytest.mark.parametrize(("fmt", "options"), POLYGON_FORMATS)
def test_polygon_formats_round_trip_exactly(name, fmt, options):
    mesh = MESHES[name]()
    data = export_mesh(mesh, fmt, **options)
    back = load_mesh(data, file_type=fmt)
    assert np.array_equal(back.vertices, mesh.vertices)
    assert np.array_equal(back.face_indices, mesh.face_indices)
    assert np.array_equal(back.face_offsets, mesh.face_offsets)
    assert load_mesh(data).n_faces == mesh.n_faces  # recognised from the content too


@pytest.mark.parametrize("name", sorted(MESHES))
@pytest.mark.parametrize("fmt", ["glb", "gltf"])
def test_gltf_round_trip_keeps_orientation(name, fmt):
    mesh = MESHES[name]()
    data = export_mesh(mesh, fmt)
    back = load_mesh(data, file_type=fmt)
    triangles, source = triangulate_faces(mesh)
    assert back.is_triangle_mesh()
    assert np.array_equal(back.face_indices.reshape(-1, 3), triangles)
    assert np.allclose(back.vertices, mesh.vertices, atol=1e-6)
    volume = signed_volume(back.vertices, triangles)
    assert volume > 0
    assert volume == pytest.approx(signed_volume(mesh.vertices, triangles), rel=1e-5)
    corners = back.vertices[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    agree = np.einsum("ij,ij->i", normals, newell_normals(mesh)[source])
    assert np.all(agree > 0)


def test_glb_structure_is_valid_gltf():
    data = export_mesh(l_prism(), "glb")
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_length % 4 == 0
    doc = json.loads(data[20 : 20 + json_length])
    assert doc["asset"]["version"] == "2.0"
    primitive = doc["meshes"][0]["primitives"][0]
    position = doc["accessors"][primitive["attributes"]["POSITION"]]
    assert position["componentType"] == 5126 and position["type"] == "VEC3"
    assert np.allclose(position["min"], [0, 0, 0]) and np.allclose(position["max"], [2, 2, 0.5])
    assert doc["accessors"][primitive["indices"]]["componentType"] == 5125
    bin_length, bin_type = struct.unpack_from("<II", data, 20 + json_length)
    assert bin_type == 0x004E4942 and bin_length >= doc["buffers"][0]["byteLength"]


def test_gltf_embeds_base64_buffer():
    doc = json.loads(export_mesh(cube(), "gltf"))
    uri = doc["buffers"][0]["uri"]
    assert uri.startswith("data:application/octet-stream;base64,")
    assert len(base64.b64decode(uri.split(",", 1)[1])) == doc["buffers"][0]["byteLength"]


@pytest.mark.parametrize("name", sorted(MESHES))
def test_stl_binary_and_ascii_weld_to_the_vertex_count(name):
    mesh = MESHES[name]()
    triangles, _ = triangulate_faces(mesh)
    binary = export_mesh(mesh, "stl")
    assert not binary.startswith(b"solid")
    lines = ["solid test"]
    for tri in mesh.vertices[triangles]:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x!r} {y!r} {z!r}" for x, y, z in tri.tolist()]
        lines += ["    endloop", "  endfacet"]
    ascii_stl = ("\n".join([*lines, "endsolid test"]) + "\n").encode()
    for data, tolerance in ((binary, 1e-6), (ascii_stl, 0.0)):
        back = load_mesh(data, file_type="stl")
        assert back.n_vertices == mesh.n_vertices
        assert back.n_faces == len(triangles)
        assert check_topology(back).is_closed_oriented_manifold
        volume = signed_volume(back.vertices, back.face_indices.reshape(-1, 3))
        reference = signed_volume(mesh.vertices, triangles)
        assert volume == pytest.approx(reference, rel=max(tolerance, 1e-12))
        assert load_mesh(data).n_vertices == mesh.n_vertices  # sniffed


def test_binary_stl_whose_header_starts_with_solid():
    data = bytearray(export_mesh(cube(), "stl"))
    data[:80] = b"solid but binary".ljust(80)
    assert load_mesh(bytes(data), file_type="stl").n_vertices == 8


@pytest.mark.parametrize("fmt", SUPPORTED_MESH_WRITE)
def test_save_and_load_by_extension(tmp_path, fmt):
    path = tmp_path / f"mesh.{fmt.upper()}"
    save_mesh(pentagon_prism(), path)
    back = load_mesh(path)
    assert back.n_vertices == 10
    expected = 7 if fmt in ("obj", "off", "ply") else 2 * 3 + 5 * 2
    assert back.n_faces == expected
    with open(path, "rb") as handle:
        assert load_mesh(handle).n_faces == expected


def test_file_type_may_be_a_file_name():
    data = export_mesh(cube(), "off")
    assert load_mesh(data, file_type="upload.OFF").n_faces == 6
    assert load_mesh(io.BytesIO(data), file_type=".off").n_faces == 6


def test_supported_lists():
    assert set(SUPPORTED_MESH_READ) == {"glb", "gltf", "obj", "off", "ply", "stl"}
    assert {"glb", "gltf", "obj", "off", "ply"} <= set(SUPPORTED_MESH_WRITE)


# ---------------------------------------------------------------------- format variants
def test_off_face_wrapped_over_lines_and_header_variants():
    text = """OFF
# a comment line
4 2 0
0 0 0
1 0 0   # trailing comment
1 1 0
0 1 0
4 0 1
  2
3
3 0 2 3
"""
    mesh = load_mesh(text.encode(), file_type="off")
    assert mesh.faces[0].tolist() == [0, 1, 2, 3]
    assert mesh.faces[1].tolist() == [0, 2, 3]


@pytest.mark.parametrize(
    "text",
    [
        "OFF 4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
        "COFF\n4 1 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n1 1 0 0 0 0 1\n0 1 0 1 1 1 1\n"
        "4 0 1 2 3 255 0 0\n",
        "NOFF\n4 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n1 1 0 0 0 1\n0 1 0 0 0 1\n4 0 1 2 3\n",
        "4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",  # no keyword
        "OFF\n4 1 0\n0 0 0 1 0 0 1 1 0 0 1 0 4 0 1 2 3\n",  # one token stream
        "\ufeffOFF\r\n4 1 0\r\n0 0 0\r\n1 0 0\r\n1 1 0\r\n0 1 0\r\n4 0 1 2 3\r\n",
    ],
)
def test_off_variants(text):
    mesh = load_mesh(text.encode("utf-8"), file_type="off")
    assert mesh.n_vertices == 4
    assert mesh.faces[0].tolist() == [0, 1, 2, 3]
    assert np.array_equal(mesh.vertices[2], [1, 1, 0])


def test_obj_negative_indices_and_corner_forms():
    text = r"""# exported by hand
mtllib scene.mtl
o square
v 0 0 0 1 0 0
v 1 0 0 0 1 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
g group
usemtl red
s 1
f 1/1/1 2/2/1 3/3/1
f -4//1 -2//1 -1//1
f 1/1 3/3 \
  4/1
l 1 2
v 2 0 0
f -1 -4 -3
"""
    mesh = load_mesh(text.encode(), file_type="obj")
    assert mesh.n_vertices == 5
    assert [f.tolist() for f in mesh.faces] == [[0, 1, 2], [0, 2, 3], [0, 2, 3], [4, 1, 2]]


def ply_header(encoding: str, n_vertices: int, n_faces: int, list_types: str) -> bytes:
    return (
        f"ply\nformat {encoding} 1.0\ncomment made by a test\n"
        f"element vertex {n_vertices}\nproperty float x\nproperty float y\n"
        "property float z\nproperty uchar red\nproperty double nx\nproperty double ny\n"
        f"property double nz\nelement face {n_faces}\nproperty uchar flags\n"
        f"property list {list_types} vertex_index\nproperty list uchar float texcoord\n"
        "element material 1\nproperty float shininess\nend_header\n"
    ).encode()


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("list_types", ["uchar int", "ushort uint", "int ushort"])
@pytest.mark.parametrize("mixed", [False, True])
def test_binary_ply_with_extra_properties(order, list_types, mixed):
    encoding = "binary_little_endian" if order == "<" else "binary_big_endian"
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float32)
    faces = [[0, 1, 2], [0, 2, 3]] if not mixed else [[0, 1, 2, 3], [3, 2, 1]]
    count_type, index_type = (
        {"uchar": "u1", "ushort": "u2", "int": "i4", "uint": "u4"}[t] for t in list_types.split()
    )
    body = b""
    for p in vertices:
        body += p.astype(order + "f4").tobytes() + b"\x07"
        body += np.array([0, 0, 1], dtype=order + "f8").tobytes()
    for face in faces:
        body += b"\x01" + np.array([len(face)], dtype=order + count_type).tobytes()
        body += np.array(face, dtype=order + index_type).tobytes()
        body += b"\x02" + np.array([0.5, 0.25], dtype=order + "f4").tobytes()
    body += np.array([3.0], dtype=order + "f4").tobytes()
    mesh = load_mesh(ply_header(encoding, 4, 2, list_types) + body, file_type="ply")
    assert np.array_equal(mesh.vertices, vertices)
    assert [f.tolist() for f in mesh.faces] == faces


def test_ascii_ply_with_extra_properties():
    text = ply_header("ascii", 3, 1, "uchar int").decode() + (
        "0 0 0 7 0 0 1\n1 0 0 7 0 0 1\n0 1 0 7 0 0 1\n1 3 0 1 2 2 0.5 0.5\n3.5\n"
    )
    mesh = load_mesh(text.encode(), file_type="ply")
    assert mesh.faces[0].tolist() == [0, 1, 2]
    assert np.array_equal(mesh.vertices[1], [1, 0, 0])


def test_large_binary_ply_mixed_faces_round_trip():
    rng = np.random.default_rng(0)
    sizes = rng.integers(3, 9, size=2000)
    indices = rng.integers(0, 500, size=int(sizes.sum()))
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    mesh = PolygonMesh(rng.normal(size=(500, 3)), indices, offsets)
    for encoding in ("binary_little_endian", "binary_big_endian", "ascii"):
        back = load_mesh(export_mesh(mesh, "ply", encoding=encoding), file_type="ply")
        assert np.array_equal(back.face_indices, mesh.face_indices)
        assert np.array_equal(back.face_offsets, mesh.face_offsets)
        assert np.array_equal(back.vertices, mesh.vertices)


def test_gltf_reader_handles_strides_types_nodes_and_no_indices():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9]], dtype="<f4")
    interleaved = np.hstack([positions, np.ones((4, 1), dtype="<f4")]).tobytes()  # stride 16
    indices = np.array([0, 1, 2], dtype="<u1").tobytes() + b"\x00"
    blob = interleaved + indices
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"children": [1, 2]}, {"mesh": 0}, {"mesh": 1, "translation": [0, 0, 5]}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
            {"primitives": [{"attributes": {"POSITION": 2}}]},  # no indices: sequential
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"},
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 64, "byteStride": 16},
            {"buffer": 0, "byteOffset": 64, "byteLength": 3},
        ],
        "buffers": [
            {
                "byteLength": len(blob),
                "uri": "data:application/gltf-buffer;base64," + base64.b64encode(blob).decode(),
            }
        ],
    }
    mesh = load_mesh(json.dumps(doc).encode(), file_type="gltf")
    assert mesh.n_vertices == 7
    assert [f.tolist() for f in mesh.faces] == [[0, 1, 2], [4, 5, 6]]
    assert np.array_equal(mesh.vertices[4:], positions[:3] + np.array([0, 0, 5]))


def test_sniffing_and_unsupported_types():
    assert sniff_file_type(export_mesh(cube(), "glb")) == "glb"
    assert sniff_file_type(export_mesh(cube(), "ply")) == "ply"
    assert sniff_file_type(b"# hi\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n") == "obj"
    with pytest.raises(UnsupportedFormatError, match=r"\.obj"):
        load_mesh(export_mesh(cube(), "obj"), file_type="fbx")
    with pytest.raises(UnsupportedFormatError, match="supported"):
        load_mesh(b"\x01\x02\x03 definitely not a mesh")
    with pytest.raises(UnsupportedFormatError):
        export_mesh(cube(), "dae")


# ---------------------------------------------------------------------- malformed input
def truncated_binary_ply() -> bytes:
    data = export_mesh(sphere(), "ply")
    return data[: len(data) // 2]


def nan_ply() -> bytes:
    mesh = cube()
    vertices = mesh.vertices.copy()
    vertices[3, 1] = np.nan
    return export_mesh(mesh.with_vertices(vertices), "ply")


MALFORMED = {
    "ply truncated binary": ("ply", truncated_binary_ply()),
    "ply truncated header": ("ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n"),
    "ply bad type": ("ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\n"
                     b"end_header\n"),
    "ply no xyz": ("ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\n"
                   b"end_header\n1\n"),
    "ply huge count": ("ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\n"
                       b"property float x\nproperty float y\nproperty float z\nend_header\n\0\0"),
    "ply ascii short": ("ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                        b"property float y\nproperty float z\nend_header\n0 0 0\n1 1 1\n"),
    "ply face out of range": ("ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                              b"property float y\nproperty float z\nelement face 1\n"
                              b"property list uchar int vertex_indices\nend_header\n"
                              b"0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
    "ply nan": ("ply", nan_ply()),
    "off face out of range": ("off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 900\n"),
    "off ends early": ("off", b"OFF\n1000 1 0\n0 0 0\n1 0 0\n"),
    "off nan": ("off", b"OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"),
    "off inf": ("off", b"OFF\n3 1 0\n0 0 0\ninf 0 0\n0 1 0\n3 0 1 2\n"),
    "off no counts": ("off", b"OFF\n"),
    "off word": ("off", b"OFF\n3 1 0\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"),
    "obj out of range": ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"),
    "obj relative too far": ("obj", b"v 0 0 0\nf -1 -2 -3\n"),
    "obj index zero": ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
    "obj nan": ("obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"),
    "obj short vertex": ("obj", b"v 0 0\n"),
    "obj no vertices": ("obj", b"# only a comment\ng nothing\n"),
    "stl truncated binary": ("stl", export_mesh(cube(), "stl")[:-30]),
    "stl short header": ("stl", b"\x00" * 40),
    "stl ascii odd vertices": ("stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                               b"vertex 1 0 0\nendloop\nendfacet\nendsolid x\n"),
    "stl nan": ("stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nan\nvertex 1 0 0\n"
                b"vertex 0 1 0\nendloop\nendfacet\nendsolid x\n"),
    "glb bad magic": ("glb", b"glTX" + b"\x00" * 40),
    "glb truncated": ("glb", export_mesh(cube(), "glb")[:100]),
    "glb missing bin": ("glb", export_mesh(cube(), "glb")[:12 + 8 + 300]),
    "gltf bad json": ("gltf", b'{"asset": {"version": "2.0"}, "meshes": [}'),
    "gltf not an object": ("gltf", b"[1, 2, 3]"),
    "gltf no meshes": ("gltf", b'{"asset": {"version": "2.0"}}'),
    "gltf bad accessor": ("gltf", b'{"asset": {"version": "2.0"}, "meshes": [{"primitives":'
                          b' [{"attributes": {"POSITION": 5}}]}]}'),
    "gltf external buffer": ("gltf", json.dumps({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": "mesh.bin"}]}).encode()),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_files_raise_mesh_format_error(case):
    fmt, data = MALFORMED[case]
    with pytest.raises(MeshFormatError) as info:
        load_mesh(data, file_type=fmt)
    message = str(info.value)
    assert message.strip()
    assert not isinstance(info.value, UnsupportedFormatError)


@pytest.mark.parametrize("fmt", SUPPORTED_MESH_READ)
@pytest.mark.parametrize("data", [b"", b"   \n\n", b"\x00\xff\xfe garbage \x81" * 7])
def test_empty_and_garbage_files(fmt, data):
    with pytest.raises(MeshFormatError, match=r"\S"):
        load_mesh(data, file_type=fmt)


def test_messages_name_the_problem():
    with pytest.raises(MeshFormatError, match="face 0 refers to vertex 900 but the file has 3"):
        load_mesh(MALFORMED["off face out of range"][1], file_type="off")
    with pytest.raises(MeshFormatError, match="PLY: file ends early: expected 42 vertices"):
        load_mesh(truncated_binary_ply(), file_type="ply")
    with pytest.raises(MeshFormatError, match="NaN"):
        load_mesh(nan_ply(), file_type="ply")
    with pytest.raises(MeshFormatError, match="line 4"):
        load_mesh(MALFORMED["obj out of range"][1], file_type="obj")


@pytest.mark.parametrize("fmt", ["obj", "off", "ply", "stl", "glb", "gltf"])
def test_every_truncation_raises_only_mesh_format_error(fmt):
    data = export_mesh(l_prism(), fmt)
    if fmt == "ply":
        data = export_mesh(l_prism(), "ply", encoding="binary_big_endian")
    for cut in sorted(set(np.linspace(0, len(data) - 1, 60).astype(int))):
        try:
            load_mesh(data[:cut], file_type=fmt)
        except MeshFormatError as error:
            assert str(error)


def test_corrupted_bytes_raise_only_mesh_format_error():
    rng = np.random.default_rng(1)
    for fmt in ("ply", "glb", "stl", "off", "obj"):
        data = np.frombuffer(export_mesh(pentagon_prism(), fmt), dtype=np.uint8)
        for _ in range(40):
            corrupted = data.copy()
            corrupted[rng.integers(0, len(data), size=4)] = rng.integers(0, 256, size=4)
            try:
                load_mesh(corrupted.tobytes(), file_type=fmt)
            except MeshFormatError as error:
                assert str(error)


def test_gltf_external_buffer_next_to_the_file(tmp_path):
    doc = json.loads(MALFORMED["gltf external buffer"][1])
    doc["meshes"][0]["primitives"][0]["mode"] = 4
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4")
    (tmp_path / "mesh.bin").write_bytes(positions.tobytes())
    (tmp_path / "scene.gltf").write_text(json.dumps(doc))
    mesh = load_mesh(tmp_path / "scene.gltf")
    assert np.array_equal(mesh.vertices, positions)
    assert [f.tolist() for f in mesh.faces] == [[0, 1, 2]]


@pytest.mark.parametrize("fmt", ["glb", "gltf", "stl"])
def test_triangle_formats_keep_folded_polygon_meshes_manifold(fmt):
    """A valid 5-vertex polygon sphere whose geometric fans would put four triangles on
    one edge: GLB, glTF and STL still hold a closed oriented manifold."""
    vertices = np.array(
        [[-2.444, 0.253, -0.580], [-1.696, 2.112, -0.300], [-2.028, 1.715, -0.219],
         [-1.938, 1.617, -0.570], [-1.934, 0.739, -0.609]]
    )
    mesh = PolygonMesh.from_faces(vertices, [[0, 2, 3, 4], [0, 4, 3, 1, 2], [1, 3, 2]])
    loaded = load_mesh(export_mesh(mesh, fmt), fmt)
    report = check_topology(loaded)
    assert report.is_closed_oriented_manifold, report.defects()
    assert loaded.n_faces == 6
