"""Mesh files: the format picked from the file type, the file name's extension or, failing
both, the content, and the bytes read or written by that format's module."""

from __future__ import annotations

import os
import re
import struct
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO, TypeAlias

from spacemesh.io import gltf, obj, off, ply, stl
from spacemesh.io.errors import MeshFormatError, UnsupportedFormatError
from spacemesh.io.las import LAS_MAGIC
from spacemesh.io.limits import UNLIMITED, ReadLimits
from spacemesh.mesh import PolygonMesh

#: A file path, the file's bytes, or an open binary file.
MeshSource: TypeAlias = "str | os.PathLike[str] | bytes | bytearray | memoryview | BinaryIO"

_READERS: dict[str, Callable[[bytes, Path | None, ReadLimits], PolygonMesh]] = {
    "glb": lambda data, base, limits: gltf.load_glb(data, base_dir=base, limits=limits),
    "gltf": lambda data, base, limits: gltf.load_gltf(data, base_dir=base, limits=limits),
    "obj": lambda data, base, limits: obj.load_obj(data, limits),
    "off": lambda data, base, limits: off.load_off(data, limits),
    "ply": lambda data, base, limits: ply.load_ply(data, limits),
    "stl": lambda data, base, limits: stl.load_stl(data, limits),
}
_WRITERS: dict[str, Callable[..., bytes]] = {
    "glb": gltf.export_glb,
    "gltf": gltf.export_gltf,
    "obj": obj.export_obj,
    "off": off.export_off,
    "ply": ply.export_ply,
    "stl": stl.export_stl,
}

#: File types :func:`load_mesh` reads.
SUPPORTED_MESH_READ: tuple[str, ...] = tuple(sorted(_READERS))
#: File types :func:`save_mesh` and :func:`export_mesh` write.
SUPPORTED_MESH_WRITE: tuple[str, ...] = tuple(sorted(_WRITERS))

_OFF_HEADER = re.compile(rb"^(ST)?C?N?4?n?OFF(\s|$|\d)")
_NUMBER_ROW = re.compile(rb"^[-+0-9.eEinfaINFA]+([\s,;]+[-+0-9.eEinfaINFA]+){2,}\s*$")


def normalize_file_type(file_type: str | os.PathLike[str] | None) -> str | None:
    """Lower-case file type from ``"ply"``, ``".PLY"`` or a file name ``"scan.ply"``.

    Parameters
    ----------
    file_type : str or PathLike, optional

    Returns
    -------
    str or None
        None when nothing is given or the name has no extension.
    """
    if file_type is None:
        return None
    text = os.fspath(file_type).strip().lower()
    if "." in text:
        text = text.rsplit(".", 1)[1]
    return text or None


def read_source(source: MeshSource) -> tuple[bytes, str | None, Path | None]:
    """The bytes of a path, bytes object or binary file.

    Parameters
    ----------
    source : path, bytes or binary file object

    Returns
    -------
    data : bytes
    extension : str or None
        The file name's extension, lower case, when the source has a name.
    folder : Path or None
        The file's folder (for glTF external buffers), for paths only.
    """
    if isinstance(source, bytes | bytearray | memoryview):
        return bytes(source), None, None
    if isinstance(source, str | os.PathLike):
        path = Path(source)
        return path.read_bytes(), normalize_file_type(path.suffix or None), path.parent
    if hasattr(source, "read"):
        data = source.read()
        if isinstance(data, str):
            data = data.encode("utf-8")
        name = getattr(source, "name", None)
        suffix = Path(name).suffix if isinstance(name, str) else ""
        extension = normalize_file_type(suffix or None)
        return bytes(data), extension, None
    raise TypeError(f"expected a path, bytes or a binary file, not {type(source).__name__}")


def sniff_file_type(data: bytes) -> str | None:
    """Guess a file type from content alone.

    Recognises PLY, NPY, NPZ, LAS/LAZ and GLB by their magic bytes, binary STL by its size,
    and JSON glTF, OFF, ASCII STL, OBJ and plain number columns (``"xyz"``) by
    their text.

    Parameters
    ----------
    data : bytes

    Returns
    -------
    str or None
        The file type, or None when the content is not recognised.
    """
    head = data[:4096]
    if head[:3] == b"ply" and head[3:4] in (b"\n", b"\r"):
        return "ply"
    if head.startswith(b"\x93NUMPY"):
        return "npy"
    if head.startswith((b"PK\x03\x04", b"PK\x05\x06")):
        return "npz"
    if head.startswith(b"glTF"):
        return "glb"
    if head.startswith(LAS_MAGIC):  # LAZ too: its header says it is compressed
        return "las"
    if stl.binary_count(data) is not None:
        return "stl"
    if b"\x00" in head:
        return None
    text = head.removeprefix(b"\xef\xbb\xbf").lstrip()
    if text.startswith(b"{"):
        return "gltf"
    if _OFF_HEADER.match(text):
        return "off"
    if text[:5].lower() == b"solid":
        return "stl"
    rows = [r.strip() for r in text.splitlines()[:-1] or text.splitlines()]
    rows = [r for r in rows if r and not r.startswith(b"#")]
    if any(r.startswith((b"v ", b"v\t", b"f ")) for r in rows):
        return "obj"
    numeric = [r for r in rows[:5] if _NUMBER_ROW.match(r)]
    if numeric and len(numeric) >= min(len(rows), 5) - 1:
        return "xyz"
    return None


def resolve_file_type(
    file_type: str | None,
    extension: str | None,
    data: bytes,
    supported: tuple[str, ...],
    what: str,
) -> str:
    """The file type to read: the one given, else the extension, else the content.

    Parameters
    ----------
    file_type : str, optional
        As passed by the caller (a type, an extension or a file name).
    extension : str, optional
        The source file's extension.
    data : bytes
        The content, sniffed when neither names a type.
    supported : tuple of str
        The types accepted.
    what : str
        "mesh" or "point cloud", for messages.

    Returns
    -------
    str
    """
    chosen = normalize_file_type(file_type) or extension
    listed = ", ".join(f".{t}" for t in supported)
    if chosen is not None:
        if chosen not in supported:
            raise UnsupportedFormatError(
                f"unsupported {what} file type '.{chosen}'; supported: {listed}"
            )
        return chosen
    sniffed = sniff_file_type(data)
    if sniffed is None or sniffed not in supported:
        if not data.strip():
            raise MeshFormatError(f"the {what} file is empty")
        raise UnsupportedFormatError(
            f"could not recognise the {what} file format from its content; supported: {listed}"
        )
    return sniffed


def load_mesh(
    source: MeshSource, file_type: str | None = None, limits: ReadLimits | None = None
) -> PolygonMesh:
    """Read a polygon mesh from a file or its bytes.

    Parameters
    ----------
    source : path, bytes or binary file object
        The file. Bytes (as uploaded to the service) are read as ``file_type``
        or, when it is not given, as whatever their content looks like.
    file_type : str, optional
        ``"obj"``, ``".off"``, ``"upload.ply"``...; overrides the extension.
    limits : ReadLimits, optional
        Counts and decoded sizes allowed, checked while reading (default: none).

    Returns
    -------
    PolygonMesh
        Polygons as stored (OBJ, OFF, PLY) or triangles (STL, glTF, GLB).

    Raises
    ------
    MeshFormatError
        The file is malformed, truncated or empty.
    TooLargeError
        The file declares or holds more than ``limits`` allow.
    UnsupportedFormatError
        The file type is not one of :data:`SUPPORTED_MESH_READ`.
    """
    data, extension, folder = read_source(source)
    fmt = resolve_file_type(file_type, extension, data, SUPPORTED_MESH_READ, "mesh")
    try:
        return _READERS[fmt](data, folder, limits or UNLIMITED)
    except MeshFormatError:
        raise
    except (ValueError, IndexError, KeyError, TypeError, struct.error, OverflowError) as exc:
        raise MeshFormatError(f"{fmt.upper()}: could not read the file ({exc})") from None


def export_mesh(mesh: PolygonMesh, file_type: str, **options) -> bytes:
    """Serialise a mesh to bytes.

    Parameters
    ----------
    mesh : PolygonMesh
    file_type : str
        One of :data:`SUPPORTED_MESH_WRITE` (or an extension or file name).
    **options
        Passed to the writer, e.g. ``encoding="ascii"`` for PLY.

    Returns
    -------
    bytes
        OBJ, OFF and PLY keep the polygons; GLB, glTF and STL hold triangles
        oriented like their polygons.
    """
    fmt = normalize_file_type(file_type)
    if fmt not in _WRITERS:
        listed = ", ".join(f".{t}" for t in SUPPORTED_MESH_WRITE)
        raise UnsupportedFormatError(f"cannot write mesh file type '.{fmt}'; supported: {listed}")
    return _WRITERS[fmt](mesh, **options)


def save_mesh(
    mesh: PolygonMesh, path: str | os.PathLike[str], file_type: str | None = None, **options
) -> None:
    """Write a mesh to a file, the format taken from ``file_type`` or the extension.

    Parameters
    ----------
    mesh : PolygonMesh
    path : path
        Where to write.
    file_type : str, optional
        Overrides the extension of ``path``.
    **options
        Passed to the writer (see :func:`export_mesh`).
    """
    fmt = normalize_file_type(file_type) or normalize_file_type(Path(path).suffix or None)
    data = export_mesh(mesh, fmt or "", **options)
    Path(path).write_bytes(data)
