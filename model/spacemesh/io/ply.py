"""Stanford PLY: ASCII and binary (little and big endian), polygons kept.

Read: a ``vertex`` element with ``x y z`` (any scalar type), optional ``nx ny nz``,
any other properties skipped (lists included), an optional ``face`` element whose
list property is named ``vertex_indices`` or ``vertex_index`` (any count and index
types), and any other elements skipped. Written: ``double`` positions and
``list uchar int vertex_indices`` faces (``list int int`` past 255 sides).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from itertools import pairwise
from typing import Any, Literal, overload

import numpy as np

from spacemesh.io.errors import (
    MeshFormatError,
    check_face_indices,
    check_vertices,
    require_nonempty,
)
from spacemesh.io.limits import UNLIMITED, ReadLimits
from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray, IntArray

_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_ENCODINGS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
_FACE_LISTS = ("vertex_indices", "vertex_index")
_SPACE = re.compile(r"\s")


@dataclass(frozen=True)
class _Property:
    name: str
    dtype: np.dtype  # item type (with byte order for binary files)
    count_dtype: np.dtype | None = None  # set for list properties


@dataclass(frozen=True)
class _Element:
    name: str
    count: int
    properties: tuple[_Property, ...]


@dataclass(frozen=True)
class PlyData:
    """What the PLY reader keeps from a file."""

    vertices: FloatArray  # (V, 3) float64
    normals: FloatArray | None  # (V, 3) float64 when the file has nx, ny, nz
    face_indices: IntArray  # (S,) int64
    face_offsets: IntArray  # (F + 1,) int64


# ---------------------------------------------------------------------- header
def _parse_header(data: bytes) -> tuple[str, list[_Element], int]:
    """The encoding, the elements, and the byte offset where the data starts."""
    if not data.startswith(b"ply"):
        raise MeshFormatError("PLY: the file does not start with 'ply'")
    end = data.find(b"\nend_header") + 1
    if end <= 0:
        raise MeshFormatError("PLY: the header has no 'end_header' line")
    newline = data.find(b"\n", end)
    start = len(data) if newline < 0 else newline + 1
    lines = data[:end].decode("latin-1").splitlines()[1:]
    encoding: str | None = None
    elements: list[tuple[str, int, list[_Property]]] = []
    for number, line in enumerate(lines, start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) < 2 or words[1] not in _ENCODINGS:
                raise MeshFormatError(f"PLY: header line {number}: unknown format '{line}'")
            encoding = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise MeshFormatError(f"PLY: header line {number}: bad element line '{line}'")
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property":
            if not elements:
                raise MeshFormatError(f"PLY: header line {number}: property before any element")
            elements[-1][2].append(_parse_property(words, number, encoding))
        else:
            raise MeshFormatError(f"PLY: header line {number}: unexpected '{words[0]}'")
    if encoding is None:
        raise MeshFormatError("PLY: the header has no 'format' line")
    return encoding, [_Element(n, c, tuple(p)) for n, c, p in elements], start


def _parse_property(words: list[str], number: int, encoding: str | None) -> _Property:
    order = _ENCODINGS.get(encoding or "ascii", "")
    if len(words) == 5 and words[1] == "list":
        count_type, item_type, name = words[2], words[3], words[4]
        if count_type not in _TYPES or item_type not in _TYPES:
            raise MeshFormatError(f"PLY: header line {number}: unknown list types")
        if _TYPES[count_type][0] == "f":
            raise MeshFormatError(f"PLY: header line {number}: a list count must be an integer")
        return _Property(
            name, np.dtype(order + _TYPES[item_type]), np.dtype(order + _TYPES[count_type])
        )
    if len(words) == 3 and words[1] in _TYPES:
        return _Property(words[2], np.dtype(order + _TYPES[words[1]]))
    raise MeshFormatError(f"PLY: header line {number}: bad property line '{' '.join(words)}'")


def _check_counts(
    elements: list[_Element], encoding: str, available: int, limits: ReadLimits
) -> None:
    """Refuse element counts over the limits, or more than the bytes present can hold.

    A binary row takes at least the sizes of its scalars and list counts; an ASCII row
    at least two characters (a digit and a separator) per property.
    """
    needed = 0
    for element in elements:
        if element.name == "vertex":
            limits.check_vertices("PLY", element.count)
        elif element.name == "face":
            limits.check_faces("PLY", element.count)
        else:
            limits.check_rows("PLY", f"'{element.name}' rows", element.count)
        if encoding == "ascii":
            needed += element.count * 2 * len(element.properties)
        else:
            needed += element.count * sum(
                (p.count_dtype or p.dtype).itemsize for p in element.properties
            )
    if needed > available + 1:
        raise MeshFormatError(
            f"PLY: file ends early: expected {', '.join(_rows(e) for e in elements)} "
            f"(at least {needed} bytes), the file holds {available}"
        )


class _Tokens:
    """The whitespace-separated tokens of a text, split only as far as they are read."""

    _BLOCK = 1 << 16  # characters split at a time

    def __init__(self, text: str) -> None:
        self.text, self.pos = text, 0
        self.items: list[str] = []

    def fill(self, count: int) -> int:
        """Split until ``count`` tokens are known (or the text ends); how many are known."""
        text, items = self.text, self.items
        while len(items) < count and self.pos < len(text):
            end = min(len(text), self.pos + self._BLOCK)
            space = _SPACE.search(text, end) if end < len(text) else None
            end = space.start() if space is not None else len(text)
            items.extend(text[self.pos : end].split())
            self.pos = end
        return len(items)

    @overload
    def __getitem__(self, key: int) -> str: ...
    @overload
    def __getitem__(self, key: slice) -> list[str]: ...

    def __getitem__(self, key: int | slice) -> str | list[str]:
        if isinstance(key, slice):
            self.fill(key.stop)
            return self.items[key]
        self.fill(key + 1)
        return self.items[key]


def _rows(element: _Element) -> str:
    """``"1000 vertices"``, ``"12 faces"`` or ``"3 'edge' rows"`` for messages."""
    plural = {"vertex": "vertices", "face": "faces"}.get(element.name)
    return f"{element.count} {plural}" if plural else f"{element.count} '{element.name}' rows"


# ---------------------------------------------------------------------- binary
def _gather(raw: np.ndarray, positions: IntArray, dtype: np.dtype) -> np.ndarray:
    """Values of ``dtype`` starting at each byte position of ``raw``."""
    if positions.size == 0:
        return np.zeros(0, dtype=dtype)
    out = np.empty((positions.size, dtype.itemsize), dtype=np.uint8)
    for byte in range(dtype.itemsize):  # one byte column at a time: small temporaries
        out[:, byte] = raw[positions + byte]
    return out.view(dtype).reshape(-1)


def _items(starts: IntArray, counts: IntArray, itemsize: int) -> IntArray:
    """Byte position of every list item, given each list's first byte and length."""
    first = np.repeat(np.cumsum(counts) - counts, counts)
    within = np.arange(int(counts.sum()), dtype=np.int64) - first
    return np.repeat(starts, counts) + within * itemsize


def _read_binary(data: bytes, pos: int, element: _Element) -> tuple[dict, int]:
    """Read one binary element: ``{name: values}`` (lists as ``(flat, counts)``)."""
    raw = np.frombuffer(data, dtype=np.uint8)
    n, props = element.count, element.properties
    ends_early = f"PLY: file ends early: expected {_rows(element)}"
    if not props:
        return {}, pos
    if not any(p.count_dtype for p in props):
        row = np.dtype([(f"p{i}", p.dtype) for i, p in enumerate(props)])
        if pos + n * row.itemsize > len(data):
            raise MeshFormatError(ends_early)
        table = np.frombuffer(data, dtype=row, count=n, offset=pos)
        values: dict[str, Any] = {p.name: table[f"p{i}"] for i, p in enumerate(props)}
        return values, pos + n * row.itemsize

    min_row = sum((p.count_dtype or p.dtype).itemsize for p in props)
    if pos + n * min_row > len(data):
        raise MeshFormatError(ends_early)
    uniform = _uniform_rows(data, pos, element)
    if uniform is not None:  # every row has the first row's list lengths
        table, lengths = uniform
        values = {}
        for i, p in enumerate(props):
            if p.count_dtype is None:
                values[p.name] = table[f"p{i}"]
            else:
                flat = table[f"p{i}"].reshape(-1)
                values[p.name] = (flat, np.full(n, lengths[i], dtype=np.int64))
        return values, pos + n * table.dtype.itemsize

    # Rows of varying length: find every property's bytes row by row.
    starts = {i: np.empty(n, dtype=np.int64) for i in range(len(props))}
    counts = {i: np.empty(n, dtype=np.int64) for i, p in enumerate(props) if p.count_dtype}
    end = _walk_rows(data, pos, element, starts, counts, ends_early)
    values = {}
    for i, p in enumerate(props):
        if p.count_dtype is None:
            values[p.name] = _gather(raw, starts[i], p.dtype)
        else:
            items = _items(starts[i], counts[i], p.dtype.itemsize)
            values[p.name] = (_gather(raw, items, p.dtype), counts[i])
    return values, end


def _uniform_rows(
    data: bytes, pos: int, element: _Element
) -> tuple[np.ndarray, dict[int, int]] | None:
    """The element as a structured array if all rows have the first row's list lengths.

    Returns
    -------
    (table, lengths) or None
        ``table`` is the (n,) structured array, ``lengths`` maps each list
        property's number to its length; None when the rows differ.
    """
    n, props = element.count, element.properties
    if n == 0:
        return None
    fields: list[tuple[Any, ...]] = []
    lengths: dict[int, int] = {}
    cursor = pos
    for i, p in enumerate(props):
        if p.count_dtype is not None:
            if cursor + p.count_dtype.itemsize > len(data):
                return None
            length = int(np.frombuffer(data, p.count_dtype, 1, cursor)[0])
            if length < 0:
                return None
            fields.append((f"c{i}", p.count_dtype))
            fields.append((f"p{i}", p.dtype, (length,)))
            lengths[i] = length
            cursor += p.count_dtype.itemsize + length * p.dtype.itemsize
        else:
            fields.append((f"p{i}", p.dtype))
            cursor += p.dtype.itemsize
    row = np.dtype(fields)
    if pos + n * row.itemsize > len(data):
        return None
    table = np.frombuffer(data, dtype=row, count=n, offset=pos)
    for i, length in lengths.items():
        if np.any(table[f"c{i}"] != length):
            return None
    return table, lengths


def _walk_rows(
    data: bytes,
    pos: int,
    element: _Element,
    starts: dict[int, IntArray],
    counts: dict[int, IntArray],
    ends_early: str,
) -> int:
    """Walk rows one by one (lists of varying length), filling ``starts``/``counts``."""
    layout: list[tuple[int, int, int, bool, Literal["little", "big"], bool]] = []
    for i, p in enumerate(element.properties):
        if p.count_dtype is None:
            layout.append((i, p.dtype.itemsize, 0, False, "little", False))
        else:
            c = p.count_dtype
            order: Literal["little", "big"] = "big" if c.byteorder == ">" else "little"
            layout.append((i, c.itemsize, p.dtype.itemsize, True, order, c.kind == "i"))
    size = len(data)
    for r in range(element.count):
        for i, head, itemsize, is_list, order, signed in layout:
            if is_list:
                if pos + head > size:
                    raise MeshFormatError(ends_early)
                length = int.from_bytes(data[pos : pos + head], order, signed=signed)
                if length < 0:
                    raise MeshFormatError(f"PLY: {element.name} {r} has a negative list length")
                starts[i][r] = pos + head
                counts[i][r] = length
                pos += head + length * itemsize
            else:
                starts[i][r] = pos
                pos += head
        if pos > size:
            raise MeshFormatError(ends_early)
    return pos


# ---------------------------------------------------------------------- ascii
def _read_ascii(
    tokens: _Tokens, at: int, element: _Element, limits: ReadLimits
) -> tuple[dict, int]:
    """Read one ASCII element from the token stream starting at token ``at``."""
    n, props = element.count, element.properties
    ends_early = f"PLY: file ends early: expected {_rows(element)}"
    if not any(p.count_dtype for p in props):
        k = len(props)
        if at + n * k > tokens.fill(at + n * k):
            raise MeshFormatError(ends_early)
        try:
            table = np.array(tokens[at : at + n * k], dtype=np.float64).reshape(n, k)
        except ValueError:
            raise MeshFormatError(f"PLY: a {element.name} value is not a number") from None
        return {p.name: table[:, i] for i, p in enumerate(props)}, at + n * k
    columns: list[list[str]] = [[] for _ in props]
    lengths: list[list[int]] = [[] for _ in props]
    corners = 0
    try:
        for _ in range(n):
            for i, p in enumerate(props):
                if p.count_dtype is None:
                    columns[i].append(tokens[at])
                    at += 1
                else:
                    length = int(tokens[at])
                    if length < 0:
                        raise MeshFormatError(f"PLY: a {element.name} list length is negative")
                    corners += length
                    limits.check_corners("PLY", corners)
                    columns[i].extend(tokens[at + 1 : at + 1 + length])
                    lengths[i].append(length)
                    at += 1 + length
    except IndexError:
        raise MeshFormatError(ends_early) from None
    except ValueError:
        raise MeshFormatError(f"PLY: a {element.name} list length is not a number") from None
    if at > tokens.fill(at):
        raise MeshFormatError(ends_early)
    values = {}
    for i, p in enumerate(props):
        try:
            flat = np.array(columns[i], dtype=np.float64)
        except ValueError:
            raise MeshFormatError(f"PLY: a {element.name} value is not a number") from None
        values[p.name] = flat if p.count_dtype is None else (flat, np.array(lengths[i]))
    return values, at


# ---------------------------------------------------------------------- reading
def parse_ply(data: bytes, limits: ReadLimits | None = None) -> PlyData:
    """Parse PLY bytes into positions, optional normals and polygon faces.

    The header's element counts are checked against ``limits`` and against the bytes
    present before any element is read; ASCII data is split only as far as it is read.

    Parameters
    ----------
    data : bytes
        The file's content.
    limits : ReadLimits, optional

    Returns
    -------
    PlyData
        Faces are empty when the file has no ``face`` element.
    """
    found = _read_elements(data, limits or UNLIMITED)
    vertex = found.get("vertex")
    if vertex is None:
        raise MeshFormatError("PLY: the file has no 'vertex' element")
    if not all(axis in vertex and not isinstance(vertex[axis], tuple) for axis in "xyz"):
        raise MeshFormatError("PLY: the vertex element has no x, y, z properties")
    vertices = np.stack([vertex[a].astype(np.float64) for a in "xyz"], axis=1)  # (V, 3)
    vertices = check_vertices(vertices, "PLY")
    normals = None
    if all(a in vertex and not isinstance(vertex[a], tuple) for a in ("nx", "ny", "nz")):
        normals = np.stack([vertex[a].astype(np.float64) for a in ("nx", "ny", "nz")], axis=1)

    indices = np.zeros(0, dtype=np.int64)
    offsets = np.zeros(1, dtype=np.int64)
    face = found.get("face")
    if face is not None:
        name = next((n for n in _FACE_LISTS if isinstance(face.get(n), tuple)), None)
        if name is None:
            raise MeshFormatError(
                "PLY: the face element has no 'vertex_indices' or 'vertex_index' list"
            )
        flat, lengths = face[name]
        if flat.dtype.kind == "f" and not np.all(flat == np.round(flat)):
            raise MeshFormatError("PLY: a face index is not a whole number")
        indices = flat.astype(np.int64)
        offsets = np.concatenate([[0], np.cumsum(lengths, dtype=np.int64)]).astype(np.int64)
        check_face_indices(indices, offsets, len(vertices), "PLY")
    return PlyData(vertices, normals, indices, offsets)


def _read_elements(data: bytes, limits: ReadLimits, until: str | None = None
                   ) -> dict[str, dict]:
    """Every element's values by name (the first of each name), read in file order and
    stopping after the element named ``until`` when given. Binary scalar columns are
    views over ``data``; ASCII ones float64."""
    require_nonempty(data, "PLY")
    encoding, elements, start = _parse_header(data)
    _check_counts(elements, encoding, len(data) - start, limits)
    found: dict[str, dict] = {}
    if encoding == "ascii":
        tokens = _Tokens(str(memoryview(data)[start:], "latin-1"))
        at = 0
        for element in elements:
            values, at = _read_ascii(tokens, at, element, limits)
            found.setdefault(element.name, values)
            if element.name == until:
                break
    else:
        pos = start
        for element in elements:
            values, pos = _read_binary(data, pos, element)
            found.setdefault(element.name, values)
            if element.name == "face" and "face" in found and found["face"] is values:
                _check_face_corners(values, limits)
            if element.name == until:
                break
    return found


@dataclass(frozen=True)
class PlyHeader:
    """What a PLY header declares.

    Attributes
    ----------
    encoding : str
        ``ascii``, ``binary_little_endian`` or ``binary_big_endian``.
    counts : dict of str to int
        Rows of each element by name (the first of each name).
    """

    encoding: str
    counts: dict[str, int]

    @property
    def binary(self) -> bool:
        """The data is binary (read as views over the bytes, without parsing text)."""
        return self.encoding != "ascii"

    @property
    def has_faces(self) -> bool:
        """The file declares at least one face."""
        return self.counts.get("face", 0) > 0


def read_ply_header(data: bytes) -> PlyHeader:
    """Read only a PLY file's header (nothing of its data).

    Parameters
    ----------
    data : bytes

    Returns
    -------
    PlyHeader

    Raises
    ------
    MeshFormatError
        Not a PLY header.
    """
    encoding, elements, _ = _parse_header(data)
    counts: dict[str, int] = {}
    for element in elements:
        counts.setdefault(element.name, element.count)
    return PlyHeader(encoding, counts)


def read_ply_vertex_columns(data: bytes, limits: ReadLimits | None = None
                            ) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...] | None]:
    """The vertex element's ``x y z`` (and ``nx ny nz``) columns, nothing converted.

    The header's counts are checked as :func:`parse_ply` checks them; the elements after
    the vertex element are not read. A binary file's columns are views over ``data``
    in the file's types (no row is copied); an ASCII file's are float64.

    Parameters
    ----------
    data : bytes
    limits : ReadLimits, optional

    Returns
    -------
    xyz : tuple of three (V,) arrays
    normals : tuple of three (V,) arrays, or None
        When the vertex element has ``nx ny nz``.

    Raises
    ------
    MeshFormatError
        No vertex element, or one without ``x y z``.
    """
    vertex = _read_elements(data, limits or UNLIMITED, until="vertex").get("vertex")
    if vertex is None:
        raise MeshFormatError("PLY: the file has no 'vertex' element")
    if not all(axis in vertex and not isinstance(vertex[axis], tuple) for axis in "xyz"):
        raise MeshFormatError("PLY: the vertex element has no x, y, z properties")
    xyz = tuple(vertex[a] for a in "xyz")
    names = ("nx", "ny", "nz")
    if all(a in vertex and not isinstance(vertex[a], tuple) for a in names):
        return xyz, tuple(vertex[a] for a in names)
    return xyz, None


def _check_face_corners(values: dict, limits: ReadLimits) -> None:
    """Refuse a binary face element whose lists hold more corners than allowed."""
    for name in _FACE_LISTS:
        if isinstance(values.get(name), tuple):
            limits.check_corners("PLY", int(values[name][1].sum()))


def load_ply(data: bytes, limits: ReadLimits | None = None) -> PolygonMesh:
    """Read a PLY file's polygons (a point cloud gives a mesh without faces).

    Parameters
    ----------
    data : bytes
        The file's content.
    limits : ReadLimits, optional
        Counts allowed (:func:`parse_ply`).

    Returns
    -------
    PolygonMesh
    """
    parsed = parse_ply(data, limits)
    return PolygonMesh(parsed.vertices, parsed.face_indices, parsed.face_offsets)


# ---------------------------------------------------------------------- writing
def export_ply(mesh: PolygonMesh, *, encoding: str = "binary_little_endian") -> bytes:
    """Write a mesh as PLY with ``double`` positions, polygons kept.

    Parameters
    ----------
    mesh : PolygonMesh
    encoding : {"binary_little_endian", "binary_big_endian", "ascii"}
        The PLY format.

    Returns
    -------
    bytes
    """
    if encoding not in _ENCODINGS:
        raise ValueError(f"PLY encoding must be one of {sorted(_ENCODINGS)}, not {encoding!r}")
    sizes = mesh.face_sizes
    count_type = "uchar" if sizes.size == 0 or sizes.max() <= 255 else "int"
    header = "\n".join(
        [
            "ply",
            f"format {encoding} 1.0",
            "comment SpaceMesh",
            f"element vertex {mesh.n_vertices}",
            "property double x",
            "property double y",
            "property double z",
            f"element face {mesh.n_faces}",
            f"property list {count_type} int vertex_indices",
            "end_header",
        ]
    )
    if encoding == "ascii":
        lines = [header]
        lines.extend(f"{x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist())
        indices = mesh.face_indices.tolist()
        offsets = mesh.face_offsets.tolist()
        lines.extend(f"{b - a} " + " ".join(map(str, indices[a:b])) for a, b in pairwise(offsets))
        return ("\n".join(lines) + "\n").encode("ascii")

    order = _ENCODINGS[encoding]
    vertex_bytes = mesh.vertices.astype(order + "f8").tobytes()
    head = 1 if count_type == "uchar" else 4
    # Face f starts at byte f * head + 4 * offsets[f]; corner c at face * head + 4 c + head.
    out = np.zeros(mesh.n_faces * head + 4 * mesh.face_indices.size, dtype=np.uint8)
    count_pos = np.arange(mesh.n_faces, dtype=np.int64) * head + 4 * mesh.face_offsets[:-1]
    count_bytes = sizes.astype(order + ("u1" if head == 1 else "i4")).view(np.uint8)
    out[count_pos[:, None] + np.arange(head)] = count_bytes.reshape(-1, head)
    corner = np.arange(mesh.face_indices.size, dtype=np.int64)
    corner_pos = mesh.face_of_corner * head + 4 * corner + head
    index_bytes = mesh.face_indices.astype(order + "i4").view(np.uint8).reshape(-1, 4)
    out[corner_pos[:, None] + np.arange(4)] = index_bytes
    return (header + "\n").encode("ascii") + vertex_bytes + out.tobytes()


__all__ = ["PlyData", "PlyHeader", "export_ply", "load_ply", "parse_ply", "read_ply_header",
           "read_ply_vertex_columns"]
