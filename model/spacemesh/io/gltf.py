"""glTF 2.0, binary (GLB) and JSON (.gltf): triangles read, triangulated meshes written.

Read: every triangle primitive (``TRIANGLES``, ``TRIANGLE_STRIP``, ``TRIANGLE_FAN``;
point and line primitives add only their positions) of every mesh instance in the
default scene, with node transforms applied, concatenated into one mesh. Indices
may have any integer component type; a primitive without indices is sequential.
Buffers: the GLB ``BIN`` chunk, base64 data URIs, and, when reading from a path,
files next to the ``.gltf``. Vertices are not welded: a seam in the file stays open.

Written: one mesh with one primitive, ``POSITION`` float32 (with min/max) relative to
its node's float64 ``translation`` (the bounding box centre, so meshes far from the
origin keep their precision; none when float32 holds the vertices exactly) and
``uint32`` indices, triangulated with :func:`spacemesh.primitives.triangulate_manifold`
so every triangle keeps its polygon's orientation and a manifold polygon mesh gives a
manifold triangle mesh (a face whose every fan would duplicate an edge gets a centroid
vertex, appended after the mesh's vertices). ``.gltf`` embeds the buffer as a
base64 data URI.
"""

from __future__ import annotations

import base64
import binascii
import json
import struct
from collections.abc import Callable
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from spacemesh.io.errors import MeshFormatError, TooLargeError, check_vertices, require_nonempty
from spacemesh.io.limits import UNLIMITED, ReadLimits, load_json
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_manifold
from spacemesh.typed import FloatArray, IntArray

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942
_COMPONENTS: dict[int, np.dtype] = {
    5120: np.dtype("<i1"),
    5121: np.dtype("<u1"),
    5122: np.dtype("<i2"),
    5123: np.dtype("<u2"),
    5125: np.dtype("<u4"),
    5126: np.dtype("<f4"),
}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_NORMALIZED_SCALE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_TRIANGLE_MODES = (4, 5, 6)
#: Most node visits while placing the scene's meshes (instancing a shared subtree
#: multiplies them).
MAX_NODE_VISITS = 100_000


class _Document:
    """A parsed glTF JSON document with its buffers, read on demand."""

    def __init__(
        self,
        doc: dict,
        fmt: str,
        binary: bytes | None,
        base_dir: Path | None,
        limits: ReadLimits = UNLIMITED,
    ) -> None:
        if not isinstance(doc, dict):
            raise MeshFormatError(f"{fmt}: the JSON document is not an object")
        version = str(doc.get("asset", {}).get("version", "2.0"))
        if not version.startswith("2"):
            raise MeshFormatError(f"{fmt}: glTF version {version} is not supported (only 2.0)")
        self.doc, self.fmt, self.binary, self.base_dir = doc, fmt, binary, base_dir
        self.limits = limits
        self._buffers: dict[int, bytes] = {}

    def buffer(self, index: int) -> bytes:
        if index not in self._buffers:
            self._buffers[index] = self._load_buffer(index)
        return self._buffers[index]

    def _load_buffer(self, index: int) -> bytes:
        spec = self.doc["buffers"][index]
        declared = int(spec.get("byteLength", 0))
        self.limits.check_bytes(self.fmt, declared, f"buffer {index}")
        uri = spec.get("uri")
        if uri is None:
            if self.binary is None:
                raise MeshFormatError(f"{self.fmt}: buffer {index} has no data (no uri, no BIN)")
            data = self.binary
        elif uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise MeshFormatError(f"{self.fmt}: buffer {index}: only base64 data URIs")
            self.limits.check_bytes(self.fmt, len(payload) * 3 // 4, f"buffer {index}")
            try:
                data = base64.b64decode(payload)
            except binascii.Error:
                raise MeshFormatError(f"{self.fmt}: buffer {index}: bad base64 data") from None
        elif self.base_dir is not None:
            path = self.base_dir / unquote(uri)
            try:
                self.limits.check_bytes(self.fmt, path.stat().st_size, f"buffer {index}")
                data = path.read_bytes()
            except OSError as exc:
                raise MeshFormatError(
                    f"{self.fmt}: buffer {index}: cannot read '{uri}' ({exc.strerror})"
                ) from None
        else:
            raise MeshFormatError(
                f"{self.fmt}: buffer {index} is the external file '{uri}'; load the .gltf "
                "from its path, or use GLB or embedded buffers"
            )
        length = int(spec.get("byteLength", len(data)))
        if len(data) < length:
            raise MeshFormatError(
                f"{self.fmt}: buffer {index} holds {len(data)} bytes, expected {length}"
            )
        return data

    def accessor(self, index: int) -> np.ndarray:
        """(count, width) values of an accessor (float64 for normalised integers)."""
        acc = self.doc["accessors"][index]
        if "sparse" in acc:
            raise MeshFormatError(f"{self.fmt}: sparse accessors are not supported")
        ctype = int(acc["componentType"])
        if ctype not in _COMPONENTS:
            raise MeshFormatError(f"{self.fmt}: accessor {index}: unknown component {ctype}")
        dtype, width, count = _COMPONENTS[ctype], _WIDTH[acc["type"]], int(acc["count"])
        if count < 0:
            raise MeshFormatError(f"{self.fmt}: accessor {index} has a negative count")
        if "bufferView" not in acc:
            return np.zeros((count, width), dtype=dtype)
        view = self.doc["bufferViews"][acc["bufferView"]]
        data = self.buffer(int(view["buffer"]))
        start = int(view.get("byteOffset", 0)) + int(acc.get("byteOffset", 0))
        element = dtype.itemsize * width
        stride = int(view.get("byteStride") or element)
        view_end = int(view.get("byteOffset", 0)) + int(view["byteLength"])
        end = start + (stride * (count - 1) + element if count else 0)
        if start < 0 or stride < element or end > min(view_end, len(data)):
            raise MeshFormatError(
                f"{self.fmt}: accessor {index} reaches past the end of its buffer "
                f"({count} items of {element} bytes)"
            )
        values = np.ndarray(
            (count, width), dtype=dtype, buffer=data, offset=start, strides=(stride, dtype.itemsize)
        ).copy()
        if acc.get("normalized") and ctype in _NORMALIZED_SCALE:
            values = np.maximum(values / _NORMALIZED_SCALE[ctype], -1.0)
        return values


def _node_matrix(node: dict) -> FloatArray:
    """(4, 4) local transform of a node (``matrix``, or translation/rotation/scale)."""
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major
    x, y, z, w = np.asarray(node.get("rotation", [0, 0, 0, 1]), dtype=np.float64)
    rotation = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    matrix = np.eye(4)
    matrix[:3, :3] = rotation * np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)
    matrix[:3, 3] = np.asarray(node.get("translation", [0, 0, 0]), dtype=np.float64)
    return matrix


def _mesh_instances(doc: dict, fmt: str = "glTF") -> list[tuple[int, FloatArray]]:
    """``(mesh, world matrix)`` for every mesh placed in the default scene."""
    nodes = doc.get("nodes", [])
    n_meshes = len(doc.get("meshes", []))
    if doc.get("scenes"):
        roots = list(doc["scenes"][int(doc.get("scene", 0))].get("nodes", []))
    else:
        children = {c for node in nodes for c in node.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    instances: list[tuple[int, FloatArray]] = []
    stack = [(int(r), np.eye(4), 0) for r in reversed(roots)]
    visits = 0
    while stack:
        index, parent, depth = stack.pop()
        if depth > 64:
            raise MeshFormatError("glTF: the node hierarchy is cyclic or too deep")
        visits += 1
        if visits > MAX_NODE_VISITS:
            raise TooLargeError(
                f"{fmt}: the scene places more than {MAX_NODE_VISITS} nodes",
                what="nodes",
                count=visits,
                limit=MAX_NODE_VISITS,
            )
        node = nodes[index]
        world = parent @ _node_matrix(node)
        if "mesh" in node:
            instances.append((int(node["mesh"]), world))
        stack.extend((int(c), world, depth + 1) for c in reversed(node.get("children", [])))
    if not instances:  # meshes but no scene placing them: take them as they are
        instances = [(m, np.eye(4)) for m in range(n_meshes)]
    return instances


def _primitive_triangles(indices: IntArray, mode: int) -> IntArray:
    """(T, 3) triangles of a TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN index list."""
    n = len(indices)
    if mode == 4:
        return indices[: n - n % 3].reshape(-1, 3)
    if n < 3:
        return np.zeros((0, 3), dtype=np.int64)
    k = np.arange(n - 2)
    if mode == 5:  # strip: every other triangle is flipped to keep one orientation
        even = k % 2 == 0
        a = indices[k]
        b = np.where(even, indices[k + 1], indices[k + 2])
        c = np.where(even, indices[k + 2], indices[k + 1])
        return np.stack([a, b, c], axis=1)
    return np.stack([np.full(n - 2, indices[0]), indices[k + 1], indices[k + 2]], axis=1)


def _to_mesh(document: _Document) -> PolygonMesh:
    fmt, doc, limits = document.fmt, document.doc, document.limits
    positions: list[FloatArray] = []
    triangles: list[IntArray] = []
    n_vertices = n_corners = 0
    for mesh_index, world in _mesh_instances(doc, fmt):
        for p, primitive in enumerate(doc["meshes"][mesh_index].get("primitives", [])):
            where = f"mesh {mesh_index} primitive {p}"
            if "POSITION" not in primitive.get("attributes", {}):
                raise MeshFormatError(f"{fmt}: {where} has no POSITION attribute")
            position = int(primitive["attributes"]["POSITION"])
            limits.check_vertices(fmt, n_vertices + _declared_count(doc, position))
            local = document.accessor(position)
            if local.shape[1] != 3:
                raise MeshFormatError(f"{fmt}: {where}: POSITION is not VEC3")
            local = local.astype(np.float64)
            placed = local @ world[:3, :3].T + world[:3, 3]  # (n, 3)
            mode = int(primitive.get("mode", 4))
            if mode in _TRIANGLE_MODES:
                if "indices" in primitive:
                    n_corners += _declared_count(doc, int(primitive["indices"]))
                    limits.check_corners(fmt, n_corners)
                    limits.check_faces(fmt, n_corners // 3)
                    raw = document.accessor(int(primitive["indices"]))
                    if raw.dtype.kind not in "ui" or raw.shape[1] != 1:
                        raise MeshFormatError(f"{fmt}: {where}: indices are not integers")
                    indices = raw.reshape(-1).astype(np.int64)
                else:
                    indices = np.arange(len(local), dtype=np.int64)
                if indices.size and (indices.min() < 0 or indices.max() >= len(local)):
                    raise MeshFormatError(
                        f"{fmt}: {where}: an index refers to vertex {int(indices.max())} "
                        f"but the primitive has {len(local)} vertices"
                    )
                tri = _primitive_triangles(indices, mode)
                if np.linalg.det(world[:3, :3]) < 0:  # a mirroring transform flips winding
                    tri = tri[:, ::-1]
                triangles.append(tri + n_vertices)
            positions.append(placed)
            n_vertices += len(local)
    if not positions:
        raise MeshFormatError(f"{fmt}: the file contains no mesh primitives")
    vertices = check_vertices(np.concatenate(positions), fmt)
    faces = np.concatenate(triangles) if triangles else np.zeros((0, 3), dtype=np.int64)
    return PolygonMesh.from_faces(vertices, faces.astype(np.int64).reshape(-1, 3))


def _declared_count(doc: dict, accessor: int) -> int:
    """The item count an accessor declares (checked against the limits before reading)."""
    count = int(doc["accessors"][accessor]["count"])
    if count < 0:
        raise MeshFormatError(f"glTF: accessor {accessor} has a negative count")
    return count


def _parse_json(text: bytes, fmt: str, limits: ReadLimits = UNLIMITED) -> dict:
    return load_json(text, f"{fmt} JSON part", limits)


def _read(document_factory: Callable[[], _Document], fmt: str) -> PolygonMesh:
    """Build the mesh, turning malformed JSON structure into MeshFormatError."""
    try:
        return _to_mesh(document_factory())
    except MeshFormatError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        raise MeshFormatError(f"{fmt}: malformed document ({type(exc).__name__}: {exc})") from None


def load_glb(
    data: bytes, *, base_dir: Path | None = None, limits: ReadLimits | None = None
) -> PolygonMesh:
    """Read a binary glTF (GLB) file's triangles.

    Declared buffer lengths and accessor counts are checked against ``limits`` (and
    against the bytes present) before any is read.

    Parameters
    ----------
    data : bytes
        The file's content.
    base_dir : Path, optional
        Folder for external buffer files (only when reading from a path).
    limits : ReadLimits, optional

    Returns
    -------
    PolygonMesh
    """
    require_nonempty(data, "GLB")
    if len(data) < 20 or data[:4] != _GLB_MAGIC:
        raise MeshFormatError("GLB: the file does not start with the 'glTF' magic")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise MeshFormatError(f"GLB: container version {version} is not supported (only 2)")
    if length > len(data):
        raise MeshFormatError(f"GLB: file ends early: header says {length} bytes")
    chunks: dict[int, bytes] = {}
    at = 12
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > length:
            raise MeshFormatError("GLB: file ends early: a chunk runs past the end")
        chunks.setdefault(kind, data[at + 8 : at + 8 + size])
        at += 8 + size
    if _CHUNK_JSON not in chunks:
        raise MeshFormatError("GLB: the file has no JSON chunk")
    limits = limits or UNLIMITED
    doc = _parse_json(chunks[_CHUNK_JSON], "GLB", limits)
    return _read(lambda: _Document(doc, "GLB", chunks.get(_CHUNK_BIN), base_dir, limits), "GLB")


def load_gltf(
    data: bytes, *, base_dir: Path | None = None, limits: ReadLimits | None = None
) -> PolygonMesh:
    """Read a JSON glTF file's triangles (buffers embedded or, from a path, external).

    Parameters
    ----------
    data : bytes
        The file's content.
    base_dir : Path, optional
        Folder for external buffer files (only when reading from a path).
    limits : ReadLimits, optional
        As for :func:`load_glb`; the JSON's values are counted before it is parsed.

    Returns
    -------
    PolygonMesh
    """
    require_nonempty(data, "glTF")
    if data[:4] == _GLB_MAGIC:
        return load_glb(data, base_dir=base_dir, limits=limits)
    limits = limits or UNLIMITED
    doc = _parse_json(data, "glTF", limits)
    return _read(lambda: _Document(doc, "glTF", None, base_dir, limits), "glTF")


def _local_origin(vertices: FloatArray) -> FloatArray:
    """Where the float32 positions are measured from: the bounding box centre (the
    node's float64 translation), so that a mesh far from the origin keeps its float64
    precision to ~1e-7 of its size; zero when float32 holds every vertex exactly."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if np.array_equal(vertices.astype(np.float32), vertices):
        return np.zeros(3)
    return (vertices.min(axis=0) + vertices.max(axis=0)) / 2


def _build(mesh: PolygonMesh, uri: str | None) -> tuple[dict, bytes]:
    """The glTF document and its binary buffer for a triangulated mesh."""
    if mesh.n_vertices == 0:
        raise ValueError("glTF cannot store a mesh without vertices")
    vertices, triangles, _ = triangulate_manifold(mesh)  # (V + C, 3), (T, 3)
    origin = _local_origin(vertices)
    positions = np.ascontiguousarray(vertices - origin, dtype="<f4")  # (V + C, 3)
    indices = np.ascontiguousarray(triangles.reshape(-1), dtype="<u4")  # (3 T,)
    blob = indices.tobytes() + positions.tobytes()  # both multiples of 4 bytes
    accessors = [
        {
            "bufferView": 0,
            "componentType": 5126,
            "count": len(positions),
            "type": "VEC3",
            "min": positions.min(axis=0).tolist(),
            "max": positions.max(axis=0).tolist(),
        }
    ]
    views = [
        {"buffer": 0, "byteOffset": indices.nbytes, "byteLength": positions.nbytes, "target": 34962}
    ]
    primitive: dict = {"attributes": {"POSITION": 0}, "mode": 4 if len(indices) else 0}
    if len(indices):
        views.append({"buffer": 0, "byteOffset": 0, "byteLength": indices.nbytes, "target": 34963})
        accessors.append(
            {"bufferView": 1, "componentType": 5125, "count": len(indices), "type": "SCALAR"}
        )
        primitive["indices"] = 1
    buffer: dict = {"byteLength": len(blob)}
    if uri is not None:
        buffer["uri"] = uri
    doc = {
        "asset": {"version": "2.0", "generator": "SpaceMesh"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": origin.tolist()} if origin.any() else {"mesh": 0}],
        "meshes": [{"primitives": [primitive]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [buffer],
    }
    return doc, blob


def export_glb(mesh: PolygonMesh) -> bytes:
    """Write a mesh as binary glTF (GLB), triangulated keeping face orientation.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    bytes
    """
    doc, blob = _build(mesh, uri=None)
    text = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    blob += b"\x00" * (-len(blob) % 4)
    length = 12 + 8 + len(text) + 8 + len(blob)
    return b"".join(
        [
            struct.pack("<4sII", _GLB_MAGIC, 2, length),
            struct.pack("<II", len(text), _CHUNK_JSON),
            text,
            struct.pack("<II", len(blob), _CHUNK_BIN),
            blob,
        ]
    )


def export_gltf(mesh: PolygonMesh) -> bytes:
    """Write a mesh as JSON glTF with the buffer embedded as a base64 data URI.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    bytes
    """
    placeholder = "data:application/octet-stream;base64,"
    doc, blob = _build(mesh, uri=placeholder)
    doc["buffers"][0]["uri"] = placeholder + base64.b64encode(blob).decode("ascii")
    return json.dumps(doc, separators=(",", ":")).encode("utf-8")


__all__ = ["export_glb", "export_gltf", "load_glb", "load_gltf"]
