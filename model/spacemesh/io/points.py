"""Point clouds: positions and optional normals from PLY, text columns, NumPy and OBJ.

Read:
- PLY: the vertex element (``nx ny nz`` as normals), with or without faces.
- XYZ / PTS / TXT / CSV: 3 or more columns separated by spaces, tabs, commas or
  semicolons; ``#`` comments; a PTS count line (a lone integer) and a non-numeric
  header row are skipped. Exactly 6 columns are ``x y z nx ny nz``, unless the last
  three are whole numbers above 1 (then they are colours and dropped).
- NPY: an (N, 3) or (N, 6) array. NPZ: ``points`` and optional ``normals``, or a
  single (N, 3) / (N, 6) array.
- OBJ: ``v`` rows, and ``vn`` rows as normals when there are as many.
- OFF, STL, GLB, glTF: the mesh's vertices, without normals.

The format is the given ``file_type``, else the file name's extension, else sniffed
from the content (``ply`` magic, ``\\x93NUMPY``, zip ``PK``, ``v`` lines, columns).
"""

from __future__ import annotations

import io
import os
import re
import struct
import tokenize
import zipfile
import zlib
from typing import IO, BinaryIO

import numpy as np

from spacemesh.io.errors import (
    MeshFormatError,
    TooLargeError,
    check_vertices,
    decode_text,
    require_nonempty,
)
from spacemesh.io.limits import UNLIMITED, ReadLimits, iter_lines
from spacemesh.io.meshes import load_mesh, read_source, resolve_file_type
from spacemesh.io.obj import parse_obj
from spacemesh.io.ply import parse_ply
from spacemesh.typed import FloatArray

_TEXT_TYPES = ("csv", "pts", "txt", "xyz")
#: File types :func:`load_points` reads.
SUPPORTED_POINTS_READ: tuple[str, ...] = tuple(
    sorted({"npy", "npz", "obj", "ply", "off", "stl", "glb", "gltf", *_TEXT_TYPES})
)
_SEPARATORS = re.compile(r"[\s,;]+")
#: What NumPy's and zipfile's readers raise on malformed bytes (headers are evaluated
#: with ``ast.literal_eval`` and older ones tokenised; members are inflated with zlib).
_ARCHIVE_ERRORS = (
    ValueError,
    OSError,
    EOFError,
    SyntaxError,
    TypeError,
    KeyError,
    NotImplementedError,
    RuntimeError,
    struct.error,
    tokenize.TokenError,
    zlib.error,
    zipfile.BadZipFile,
)
#: Most members an ``.npz`` archive may list (its central directory is read whole).
MAX_NPZ_MEMBERS = 64


def _split_normals(array: np.ndarray, fmt: str) -> tuple[FloatArray, FloatArray | None]:
    """Split an (N, 3) or (N, 6) numeric array into points and normals."""
    if array.dtype.kind not in "biuf":
        raise MeshFormatError(f"{fmt}: the array holds {array.dtype} values, not numbers")
    if array.ndim != 2 or array.shape[1] not in (3, 6):
        raise MeshFormatError(
            f"{fmt}: expected an array of shape (N, 3) or (N, 6), got {array.shape}"
        )
    array = array.astype(np.float64)
    return array[:, :3], (array[:, 3:6] if array.shape[1] == 6 else None)


def parse_xyz(
    data: bytes, fmt: str = "XYZ", limits: ReadLimits | None = None
) -> tuple[FloatArray, FloatArray | None]:
    """Parse text columns: ``x y z`` or ``x y z nx ny nz`` per line.

    Lines are read one at a time; past ``limits.max_points`` rows the reading stops
    with :class:`~spacemesh.io.errors.TooLargeError`.

    Parameters
    ----------
    data : bytes
        The file's content.
    fmt : str
        The format's name for messages.
    limits : ReadLimits, optional

    Returns
    -------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    require_nonempty(data, fmt)
    limits = limits or UNLIMITED
    text = decode_text(data, fmt)
    rows: list[list[str]] = []
    numbers: list[int] = []
    first = True
    for number, raw in enumerate(iter_lines(text), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = _SEPARATORS.split(line.strip(" ,;\t"))
        if len(tokens) == 1 and tokens[0].isdigit():
            continue  # a PTS point count
        if first and not _is_number(tokens[0]):
            first = False
            continue  # a header row such as "x,y,z"
        first = False
        limits.check_points(fmt, len(rows) + 1)
        rows.append(tokens)
        numbers.append(number)
    if not rows:
        raise MeshFormatError(f"{fmt}: the file contains no points")
    width = len(rows[0])
    if width < 3:
        raise MeshFormatError(f"{fmt}: line {numbers[0]} has {width} columns, need at least 3")
    for tokens, number in zip(rows, numbers, strict=True):
        if len(tokens) != width:
            raise MeshFormatError(
                f"{fmt}: line {number} has {len(tokens)} columns, the first row has {width}"
            )
    try:
        table = np.array([t for tokens in rows for t in tokens], dtype=np.float64)
    except ValueError:
        for tokens, number in zip(rows, numbers, strict=True):
            bad = next((t for t in tokens if not _is_number(t)), None)
            if bad is not None:
                raise MeshFormatError(f"{fmt}: line {number}: '{bad}' is not a number") from None
        raise
    table = table.reshape(len(rows), width)
    normals = None
    if width == 6:
        extra = table[:, 3:6]
        colours = np.all(extra == np.round(extra)) and np.abs(extra).max() > 1
        normals = None if colours else extra
    return table[:, :3], normals


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _npy_header(stream: IO[bytes], fmt: str) -> tuple[tuple[int, ...], np.dtype]:
    """The shape and dtype an ``.npy`` stream declares (only its header is read)."""
    try:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
        else:  # 2.0 and 3.0 share the layout (3.0's header is UTF-8)
            shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
    except _ARCHIVE_ERRORS as exc:
        raise MeshFormatError(f"{fmt}: not a readable NumPy array header ({exc})") from None
    return tuple(int(n) for n in shape), np.dtype(dtype)


def _check_npy_header(
    shape: tuple[int, ...], dtype: np.dtype, fmt: str, limits: ReadLimits, available: int
) -> None:
    """Refuse an array header before its data is read: not (N, 3) or (N, 6) numbers,
    more rows than ``max_points``, or more data than the ``available`` bytes."""
    if dtype.kind not in "biuf" or dtype.hasobject:
        raise MeshFormatError(f"{fmt}: the array holds {dtype} values, not numbers")
    if len(shape) != 2 or shape[1] not in (3, 6):
        raise MeshFormatError(f"{fmt}: expected an array of shape (N, 3) or (N, 6), got {shape}")
    limits.check_points(fmt, shape[0])
    needed = shape[0] * shape[1] * dtype.itemsize
    if needed > available:
        raise MeshFormatError(
            f"{fmt}: file ends early: the array needs {needed} bytes, the file holds {available}"
        )


def parse_npy(
    data: bytes, limits: ReadLimits | None = None
) -> tuple[FloatArray, FloatArray | None]:
    """Parse a ``.npy`` array of shape (N, 3) or (N, 6).

    The header's shape and dtype are checked against ``limits`` and the bytes present
    before the data is read.

    Parameters
    ----------
    data : bytes
    limits : ReadLimits, optional

    Returns
    -------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    stream = io.BytesIO(data)
    shape, dtype = _npy_header(stream, "NPY")
    _check_npy_header(shape, dtype, "NPY", limits or UNLIMITED, len(data) - stream.tell())
    try:
        array = np.load(io.BytesIO(data), allow_pickle=False)
    except _ARCHIVE_ERRORS as exc:
        raise MeshFormatError(f"NPY: not a readable NumPy array file ({exc})") from None
    if not isinstance(array, np.ndarray):
        raise MeshFormatError("NPY: the file does not hold a single array")
    return _split_normals(array, "NPY")


def _zip_entries(data: bytes) -> int | None:
    """The member count of a zip's end-of-central-directory record, or None if absent."""
    at = data.rfind(b"PK\x05\x06", max(0, len(data) - 65_557))
    if at < 0 or at + 22 > len(data):
        return None
    return int(struct.unpack_from("<H", data, at + 10)[0])


def _read_member(archive: zipfile.ZipFile, name: str, label: str, limits: ReadLimits) -> np.ndarray:
    """One ``.npy`` member: declared size and header checked, then the data read."""
    info = archive.getinfo(name)
    limits.check_bytes(label, info.file_size, f"member '{name}' (uncompressed)")
    with archive.open(info) as stream:
        shape, dtype = _npy_header(stream, label)
        header_size = stream.tell()
    _check_npy_header(shape, dtype, label, limits, info.file_size - header_size)
    with archive.open(info) as stream:
        array = np.lib.format.read_array(stream, allow_pickle=False)
    return np.asarray(array)


def parse_npz(
    data: bytes, limits: ReadLimits | None = None
) -> tuple[FloatArray, FloatArray | None]:
    """Parse a ``.npz`` archive: ``points`` (+ ``normals``) or one array.

    Only the members used are read; each one's declared uncompressed size and its
    ``.npy`` header (shape, dtype) are checked against ``limits`` before its data is
    inflated, so a small archive that inflates to gigabytes is refused at once.

    Parameters
    ----------
    data : bytes
    limits : ReadLimits, optional

    Returns
    -------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    limits = limits or UNLIMITED
    entries = _zip_entries(data)
    if entries is not None and entries > MAX_NPZ_MEMBERS:
        raise TooLargeError(
            f"NPZ: the archive lists {entries} members; at most {MAX_NPZ_MEMBERS} are read",
            what="members",
            count=entries,
            limit=MAX_NPZ_MEMBERS,
        )
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            members = {n.removesuffix(".npy"): n for n in archive.namelist()}
            if len(members) > MAX_NPZ_MEMBERS:
                raise TooLargeError(
                    f"NPZ: the archive lists {len(members)} members; at most "
                    f"{MAX_NPZ_MEMBERS} are read",
                    what="members",
                    count=len(members),
                    limit=MAX_NPZ_MEMBERS,
                )
            if "points" in members:
                wanted: list[str] = [k for k in ("points", "normals") if k in members]
            elif len(members) == 1:
                wanted = list(members)
            else:
                raise MeshFormatError(
                    "NPZ: expected an array named 'points' "
                    f"(found {', '.join(sorted(members)) or 'none'})"
                )
            arrays = {k: _read_member(archive, members[k], "NPZ", limits) for k in wanted}
    except MeshFormatError:
        raise
    except _ARCHIVE_ERRORS as exc:
        raise MeshFormatError(f"NPZ: not a readable NumPy archive ({exc})") from None
    if "points" in arrays:
        points, normals = _split_normals(arrays["points"], "NPZ")
        if "normals" in arrays:
            normals, _ = _split_normals(np.asarray(arrays["normals"]), "NPZ normals")
            if normals.shape != points.shape:
                raise MeshFormatError(f"NPZ: {len(normals)} normals for {len(points)} points")
        return points, normals
    return _split_normals(next(iter(arrays.values())), "NPZ")


def _parse(fmt: str, data: bytes, limits: ReadLimits) -> tuple[FloatArray, FloatArray | None]:
    mesh_limits = limits.for_points()  # a mesh file's vertices are the points
    if fmt == "ply":
        parsed = parse_ply(data, mesh_limits)
        return parsed.vertices, parsed.normals
    if fmt == "obj":
        parsed_obj = parse_obj(data, mesh_limits)
        same = len(parsed_obj.normals) == len(parsed_obj.vertices)
        return parsed_obj.vertices, parsed_obj.normals if same else None
    if fmt == "npy":
        return parse_npy(data, limits)
    if fmt == "npz":
        return parse_npz(data, limits)
    if fmt in _TEXT_TYPES:
        return parse_xyz(data, fmt.upper(), limits)

    return load_mesh(data, file_type=fmt, limits=mesh_limits).vertices, None


def load_points(
    path_or_bytes: str | os.PathLike[str] | bytes | BinaryIO,
    file_type: str | None = None,
    limits: ReadLimits | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Read a point cloud, with normals when the file has them.

    Parameters
    ----------
    path_or_bytes : path, bytes or binary file object
        The file. Bytes (an upload) are read as ``file_type`` or, when it is not
        given, as whatever their content looks like.
    file_type : str, optional
        ``"ply"``, ``".xyz"``, ``"scan.npz"``...; overrides the extension.
    limits : ReadLimits, optional
        Counts and decoded sizes allowed, checked while reading (default: none).

    Returns
    -------
    points : (N, 3) float64
        Finite positions, ``N >= 1``.
    normals : (N, 3) float64 or None
        Per-point normals as stored (not renormalised), or None.

    Raises
    ------
    MeshFormatError
        The file is malformed or holds no points.
    TooLargeError
        The file declares or holds more than ``limits`` allow.
    UnsupportedFormatError
        The file type is not one of :data:`SUPPORTED_POINTS_READ`.
    """

    data, extension, _ = read_source(path_or_bytes)
    fmt = resolve_file_type(file_type, extension, data, SUPPORTED_POINTS_READ, "point cloud")
    label = fmt.upper()
    require_nonempty(data, label)
    try:
        points, normals = _parse(fmt, data, limits or UNLIMITED)
    except MeshFormatError:
        raise
    except (ValueError, IndexError, KeyError, TypeError, OverflowError) as exc:
        raise MeshFormatError(f"{label}: could not read the file ({exc})") from None
    points = check_vertices(points, label, what="point")
    if normals is not None:
        normals = check_vertices(normals, label, what="normal")
    return np.ascontiguousarray(points), (
        None if normals is None else np.ascontiguousarray(normals, dtype=np.float64)
    )


__all__ = ["SUPPORTED_POINTS_READ", "load_points", "parse_npy", "parse_npz", "parse_xyz"]
