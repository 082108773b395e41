"""Mesh files the service answers, read and written with numpy alone.

Readers for every output format of the service (JSON, OBJ, OFF, PLY, GLB, glTF) return
``(vertices, faces)``: a (V, 3) float64 array and a list of int64 index arrays, one per
polygon. GLB and glTF carry triangles only (the service triangulates them), so polygons
survive in ``json``, ``obj``, ``ply`` and ``off``. Writers keep polygons in the same four
and write GLB and glTF from a fan triangulation that keeps manifold meshes manifold.

This is the client's own small reader, not the model package's ``spacemesh.io``: the SDK
depends on no other SpaceMesh package.
"""

from __future__ import annotations

import base64
import json
import struct
from collections.abc import Sequence
from typing import Any

import numpy as np

Faces = list[np.ndarray]

#: Output format -> media type (as the service sends them).
MEDIA_TYPES: dict[str, str] = {
    "glb": "model/gltf-binary",
    "gltf": "model/gltf+json",
    "obj": "model/obj",
    "ply": "model/x-ply",
    "off": "model/x-off",
    "json": "application/json",
}
#: Formats whose faces are polygons (GLB and glTF hold triangles).
POLYGON_FORMATS = ("json", "obj", "ply", "off")
#: Formats :func:`write_mesh` writes.
WRITTEN = (*POLYGON_FORMATS, "glb", "gltf")


class FormatError(ValueError):
    """A mesh file this client cannot read."""


# ---------------------------------------------------------------------- readers
def _read_json(data: bytes) -> tuple[np.ndarray, Faces]:
    body = json.loads(data)
    vertices = np.asarray(body["vertices"], dtype=np.float64).reshape(-1, 3)
    return vertices, [np.asarray(f, dtype=np.int64) for f in body["faces"]]


def _read_obj(data: bytes) -> tuple[np.ndarray, Faces]:
    vertices: list[list[float]] = []
    faces: Faces = []
    for line in data.decode("utf-8", "replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(v) for v in parts[1:4]])
        elif parts[0] == "f":
            idx = np.array([int(p.split("/")[0]) for p in parts[1:]], dtype=np.int64)
            faces.append(np.where(idx < 0, idx + len(vertices), idx - 1))
    return np.asarray(vertices, dtype=np.float64).reshape(-1, 3), faces


def _read_off(data: bytes) -> tuple[np.ndarray, Faces]:
    lines = (line.split("#", 1)[0].split() for line in data.decode("utf-8").splitlines())
    tokens = [t for line in lines for t in line]
    if not tokens or not tokens[0].endswith("OFF"):
        raise FormatError("not an OFF file")
    rest = tokens[1:]
    n_vertices, n_faces = int(rest[0]), int(rest[1])
    position = 3
    vertices = np.asarray(rest[position:position + 3 * n_vertices], dtype=np.float64)
    position += 3 * n_vertices
    faces: Faces = []
    for _ in range(n_faces):
        count = int(rest[position])
        faces.append(np.asarray(rest[position + 1:position + 1 + count], dtype=np.int64))
        position += 1 + count
    return vertices.reshape(-1, 3), faces


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _read_ply(data: bytes) -> tuple[np.ndarray, Faces]:
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise FormatError("not a PLY file")
    body_start = data.index(b"\n", end) + 1
    encoding = "ascii"
    elements: list[tuple[str, int, list[tuple[str, ...]]]] = []
    for line in data[:end].decode("ascii").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "format":
            encoding = parts[1]
        elif parts[0] == "element":
            elements.append((parts[1], int(parts[2]), []))
        elif parts[0] == "property":
            elements[-1][2].append(tuple(parts[1:]))
    vertices = np.zeros((0, 3))
    faces: Faces = []
    if encoding == "ascii":
        rows = iter(data[body_start:].decode("ascii").splitlines())
        for name, count, props in elements:
            table = [next(rows).split() for _ in range(count)]
            if name == "vertex":
                names = [p[-1] for p in props]
                cols = [names.index(axis) for axis in "xyz"]
                vertices = np.asarray([[float(r[c]) for c in cols] for r in table]).reshape(-1, 3)
            elif name == "face":
                faces = [np.asarray(r[1:1 + int(r[0])], dtype=np.int64) for r in table]
        return vertices, faces
    order = "<" if encoding == "binary_little_endian" else ">"
    offset = body_start
    for name, count, props in elements:
        if all(p[0] != "list" for p in props):
            dtype = np.dtype([(p[-1], order + _PLY_TYPES[p[0]]) for p in props])
            records = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
            offset += dtype.itemsize * count
            if name == "vertex":
                vertices = np.stack([records[a].astype(np.float64) for a in "xyz"], axis=1)
            continue
        if len(props) != 1:
            raise FormatError(f"PLY element {name!r}: only a single list property is read")
        _, count_type, item_type, _ = props[0]
        count_dtype = np.dtype(order + _PLY_TYPES[count_type])
        item_dtype = np.dtype(order + _PLY_TYPES[item_type])
        lists: Faces = []
        for _ in range(count):
            n = int(np.frombuffer(data, count_dtype, 1, offset)[0])
            offset += count_dtype.itemsize
            lists.append(np.frombuffer(data, item_dtype, n, offset).astype(np.int64))
            offset += item_dtype.itemsize * n
        if name == "face":
            faces = lists
    return vertices, faces


_GLTF_COMPONENTS = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
_GLTF_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _gltf_arrays(doc: dict, buffers: Sequence[bytes]) -> tuple[np.ndarray, Faces]:
    def accessor(index: int) -> np.ndarray:
        acc = doc["accessors"][index]
        view = doc["bufferViews"][acc["bufferView"]]
        width = _GLTF_WIDTH[acc["type"]]
        dtype = np.dtype("<" + _GLTF_COMPONENTS[acc["componentType"]])
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        flat = np.frombuffer(buffers[view["buffer"]], dtype, acc["count"] * width, start)
        return flat.reshape(acc["count"], width)

    primitive = doc["meshes"][0]["primitives"][0]
    vertices = accessor(primitive["attributes"]["POSITION"]).astype(np.float64)
    node: dict[str, Any] = next((n for n in doc.get("nodes", []) if n.get("mesh") == 0), {})
    if "matrix" in node:  # column-major 4x4
        matrix = np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
        vertices = vertices @ matrix[:3, :3].T + matrix[:3, 3]
    vertices = vertices + np.asarray(node.get("translation", [0.0] * 3), dtype=np.float64)
    if "indices" not in primitive:
        return vertices, []
    triangles = accessor(primitive["indices"]).reshape(-1, 3).astype(np.int64)
    return vertices, list(triangles)


def _read_glb(data: bytes) -> tuple[np.ndarray, Faces]:
    magic, _, _ = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF":
        raise FormatError("not a GLB file")
    json_length, _ = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + json_length])
    bin_start = 20 + json_length
    binary = b""
    if bin_start + 8 <= len(data):
        bin_length, _ = struct.unpack_from("<II", data, bin_start)
        binary = data[bin_start + 8:bin_start + 8 + bin_length]
    return _gltf_arrays(doc, [binary])


def _read_gltf(data: bytes) -> tuple[np.ndarray, Faces]:
    doc = json.loads(data)
    buffers = [base64.b64decode(b["uri"].split(",", 1)[1]) for b in doc["buffers"]]
    return _gltf_arrays(doc, buffers)


_READERS = {"json": _read_json, "obj": _read_obj, "off": _read_off, "ply": _read_ply,
            "glb": _read_glb, "gltf": _read_gltf}


def read_mesh(data: bytes, fmt: str) -> tuple[np.ndarray, Faces]:
    """Vertices and faces of a mesh file in one of the service's formats.

    Parameters
    ----------
    data : bytes
    fmt : str
        ``json``, ``obj``, ``off``, ``ply``, ``glb`` or ``gltf``.

    Returns
    -------
    vertices : (V, 3) float64
    faces : list of (k,) int64
    """
    reader = _READERS.get(fmt)
    if reader is None:
        raise FormatError(f"cannot read {fmt!r} meshes; readable: {', '.join(_READERS)}")
    try:
        return reader(data)
    except FormatError:
        raise
    except (ValueError, KeyError, IndexError, TypeError, struct.error) as error:
        raise FormatError(f"cannot read this {fmt} mesh: {error}") from error


# ---------------------------------------------------------------------- writers
def _rows(vertices: np.ndarray) -> list[str]:
    return [f"{x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]


def triangulate(vertices: np.ndarray, faces: Faces, centroids: bool = True
                ) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of the polygons, as manifold as the polygons are.

    Each polygon is fanned from its first corner whose fan adds only new edges (a fan
    whose diagonal is already an edge, or another face's diagonal, would put four
    triangles on one edge of a valid polygon mesh). When no corner's fan is free, a
    vertex at the face's centroid is fanned to every side (``centroids=True``) or the
    first corner is used anyway (``centroids=False``). Orientation is kept; the fans
    are exact for convex faces.

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : list of (k,) int
    centroids : bool
        Add centroid vertices where no fan is free.

    Returns
    -------
    vertices : (V + C, 3) float64
        The input vertices, then the ``C`` centroids added.
    triangles : (T, 3) int64
    """
    edge_set = {(min(a, b), max(a, b)) for f in faces
                for a, b in zip(f.tolist(), np.roll(f, -1).tolist(), strict=True)}
    extra: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    for f in faces:
        k = len(f)
        if k < 3:
            continue
        chosen = None
        for apex in range(k) if k > 3 else (0,):
            ring = np.roll(f, -apex)  # (k,) apex first
            diagonals = {(min(ring[0], b), max(ring[0], b)) for b in ring[2:-1].tolist()}
            if k == 3 or not diagonals & edge_set:
                chosen = ring
                edge_set |= diagonals
                break
        if chosen is not None or not centroids:
            ring = f if chosen is None else chosen
            tris.append(np.stack([np.full(k - 2, ring[0]), ring[1:-1], ring[2:]], axis=1))
        else:
            centre = len(vertices) + len(extra)
            extra.append(vertices[f].mean(axis=0))
            tris.append(np.stack([f, np.roll(f, -1), np.full(k, centre)], axis=1))
    out = np.concatenate([vertices, np.array(extra)]) if extra else vertices
    triangles = np.concatenate(tris).astype(np.int64) if tris else np.zeros((0, 3), np.int64)
    return out, triangles


def write_mesh(vertices: np.ndarray, faces: Faces, fmt: str) -> bytes:
    """A mesh file: ``json``, ``obj``, ``off`` and ASCII ``ply`` keep the polygons;
    ``glb`` and ``gltf`` hold their triangulation (:func:`triangulate`).

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : list of (k,) int
    fmt : str
        One of :data:`WRITTEN`.

    Returns
    -------
    bytes
    """
    if fmt in ("glb", "gltf"):
        return _write_gltf(*triangulate(vertices, faces), fmt)
    face_rows = [" ".join(map(str, f.tolist())) for f in faces]
    if fmt == "json":
        body = {"vertices": vertices.tolist(), "faces": [f.tolist() for f in faces]}
        return json.dumps(body, separators=(",", ":")).encode()
    if fmt == "obj":
        lines = [f"v {row}" for row in _rows(vertices)]
        lines += ["f " + " ".join(str(i + 1) for i in f.tolist()) for f in faces]
    elif fmt == "off":
        lines = ["OFF", f"{len(vertices)} {len(faces)} 0", *_rows(vertices)]
        lines += [f"{len(f)} {row}" for f, row in zip(faces, face_rows, strict=True)]
    elif fmt == "ply":
        count = "uchar" if all(len(f) <= 255 for f in faces) else "int"
        lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
                 "property double x", "property double y", "property double z",
                 f"element face {len(faces)}", f"property list {count} int vertex_indices",
                 "end_header", *_rows(vertices)]
        lines += [f"{len(f)} {row}" for f, row in zip(faces, face_rows, strict=True)]
    else:
        raise FormatError(f"cannot write {fmt!r} without trimesh; "
                          f"written natively: {', '.join(WRITTEN)}")
    return ("\n".join(lines) + "\n").encode()


def _write_gltf(vertices: np.ndarray, triangles: np.ndarray, fmt: str) -> bytes:
    """GLB or glTF (buffer embedded) of a triangle mesh, as the service writes them:
    float32 positions relative to the node's float64 translation (the bounding box
    centre, none when float32 holds the vertices exactly)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    origin = np.zeros(3)
    if len(vertices) and not np.array_equal(vertices.astype(np.float32), vertices):
        origin = (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    positions = np.ascontiguousarray(vertices - origin, dtype="<f4")  # (V, 3)
    indices = np.ascontiguousarray(triangles.reshape(-1), dtype="<u4")  # (3 T,)
    blob = indices.tobytes() + positions.tobytes()
    lo = positions.min(axis=0).tolist() if len(positions) else [0.0] * 3
    hi = positions.max(axis=0).tolist() if len(positions) else [0.0] * 3
    doc: dict = {
        "asset": {"version": "2.0", "generator": "spacemesh-client"},
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": origin.tolist()} if origin.any() else {"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5125, "count": len(indices), "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": indices.nbytes, "byteLength": positions.nbytes},
            {"buffer": 0, "byteOffset": 0, "byteLength": indices.nbytes},
        ],
        "buffers": [{"byteLength": len(blob)}],
    }
    if fmt == "gltf":
        uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode("ascii")
        doc["buffers"][0]["uri"] = uri
        return json.dumps(doc, separators=(",", ":")).encode()
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\x00" * (-len(blob) % 4)
    return b"".join([
        struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob)),
        struct.pack("<II", len(text), 0x4E4F534A), text,
        struct.pack("<II", len(blob), 0x004E4942), blob,
    ])
