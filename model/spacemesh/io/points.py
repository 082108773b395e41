"""Point clouds: positions and optional normals from PLY, text columns, NumPy and OBJ.

Read:
- PLY: the vertex element (``nx ny nz`` as normals), with or without faces.
- XYZ / PTS / TXT / CSV: 3 or more columns separated by spaces, tabs, commas or
  semicolons; ``#`` comments; a PTS count line (a lone integer) and a non-numeric
  header row are skipped. Exactly 6 columns are ``x y z nx ny nz``, unless the last
  three are whole numbers above 1 (then they are colours and dropped).
- NPY: an (N, 3) or (N, 6) array. NPZ: ``points`` and optional ``normals``, or a
  single (N, 3) / (N, 6) array.
- LAS / LAZ: the scaled positions (:mod:`spacemesh.io.las`; LAS has no normals), read
  a block at a time, keeping only the rows the cloud is reduced to.
- OBJ: ``v`` rows, and ``vn`` rows as normals when there are as many.
- OFF, STL, GLB, glTF: the mesh's vertices, without normals.

The format is the given ``file_type``, else the file name's extension, else sniffed
from the content (``ply`` magic, ``\\x93NUMPY``, zip ``PK``, ``LASF``, ``v`` lines,
columns).
"""

from __future__ import annotations

import io
import os
import re
import struct
import tokenize
import zipfile
import zlib
from dataclasses import dataclass, replace
from typing import IO, BinaryIO

import numpy as np

from spacemesh.io.errors import (
    MeshFormatError,
    NonFiniteError,
    TooLargeError,
    check_vertices,
    decode_text,
    require_nonempty,
)
from spacemesh.io.las import LAS_TYPES, read_las
from spacemesh.io.limits import UNLIMITED, ReadLimits, iter_lines
from spacemesh.io.meshes import load_mesh, read_source, resolve_file_type
from spacemesh.io.obj import parse_obj
from spacemesh.io.ply import read_ply_header, read_ply_vertex_columns
from spacemesh.io.reduce import REDUCE_SEED, reduce_cloud
from spacemesh.typed import FloatArray

_TEXT_TYPES = ("csv", "pts", "txt", "xyz")
#: File types :func:`load_points` reads.
SUPPORTED_POINTS_READ: tuple[str, ...] = tuple(
    sorted({"npy", "npz", *LAS_TYPES, "obj", "ply", "off", "stl", "glb", "gltf",
            *_TEXT_TYPES})
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


def _split_normals(array: np.ndarray, fmt: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Split an (N, 3) or (N, 6) numeric array into points and normals (views, in the
    array's dtype)."""
    if array.dtype.kind not in "biuf":
        raise MeshFormatError(f"{fmt}: the array holds {array.dtype} values, not numbers")
    if array.ndim != 2 or array.shape[1] not in (3, 6):
        raise MeshFormatError(
            f"{fmt}: expected an array of shape (N, 3) or (N, 6), got {array.shape}"
        )
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


def _npy_header(stream: IO[bytes], fmt: str) -> tuple[tuple[int, ...], np.dtype, bool]:
    """The shape, dtype and Fortran order an ``.npy`` stream declares (only its header is
    read)."""
    try:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(stream)
        else:  # 2.0 and 3.0 share the layout (3.0's header is UTF-8)
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(stream)
    except _ARCHIVE_ERRORS as exc:
        raise MeshFormatError(f"{fmt}: not a readable NumPy array header ({exc})") from None
    return tuple(int(n) for n in shape), np.dtype(dtype), bool(fortran)


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


def _npy_view(data: bytes | memoryview, fmt: str, limits: ReadLimits) -> np.ndarray:
    """The (N, 3) or (N, 6) array of ``.npy`` bytes: a view over them (nothing copied),
    its header checked against ``limits`` and the bytes present first."""
    stream = io.BytesIO(data)
    shape, dtype, fortran = _npy_header(stream, fmt)
    start = stream.tell()
    _check_npy_header(shape, dtype, fmt, limits, len(data) - start)
    try:
        flat = np.frombuffer(data, dtype=dtype, count=shape[0] * shape[1], offset=start)
    except _ARCHIVE_ERRORS as exc:
        raise MeshFormatError(f"{fmt}: not a readable NumPy array file ({exc})") from None
    return flat.reshape(shape, order="F" if fortran else "C")


def _rows_npy(data: bytes, limits: ReadLimits) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (and normals) of ``.npy`` bytes as views in the file's dtype."""
    return _split_normals(_npy_view(data, "NPY", limits), "NPY")


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
    return reduce_cloud(*_rows_npy(data, limits or UNLIMITED), None)


def _zip_entries(data: bytes) -> int | None:
    """The member count of a zip's end-of-central-directory record, or None if absent."""
    at = data.rfind(b"PK\x05\x06", max(0, len(data) - 65_557))
    if at < 0 or at + 22 > len(data):
        return None
    return int(struct.unpack_from("<H", data, at + 10)[0])


def _read_member(archive: zipfile.ZipFile, name: str, label: str, limits: ReadLimits) -> np.ndarray:
    """One ``.npy`` member: declared size and header checked, then its bytes inflated
    once and viewed as its array."""
    info = archive.getinfo(name)
    limits.check_bytes(label, info.file_size, f"member '{name}' (uncompressed)")
    with archive.open(info) as stream:
        shape, dtype, _ = _npy_header(stream, label)
        header_size = stream.tell()
    _check_npy_header(shape, dtype, label, limits, info.file_size - header_size)
    return _npy_view(archive.read(info), label, limits)


def _rows_npz(data: bytes, limits: ReadLimits) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (and normals) of ``.npz`` bytes in the file's dtype (each member inflated
    once)."""
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
            normals, _ = _split_normals(arrays["normals"], "NPZ normals")
            if normals.shape != points.shape:
                raise MeshFormatError(f"NPZ: {len(normals)} normals for {len(points)} points")
        return points, normals
    return _split_normals(next(iter(arrays.values())), "NPZ")


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
    return reduce_cloud(*_rows_npz(data, limits or UNLIMITED), None)


#: Rows of a cloud as read: an (N, 3) array, or its three (N,) columns, of any numeric
#: dtype, maybe views over the file's bytes.
Rows = np.ndarray | tuple[np.ndarray, ...]
#: The formats whose rows are views over the file's bytes (binary PLY too), or read a
#: block at a time (LAS, LAZ): the ``max_points`` limit applies to them,
#: ``max_text_points`` to every other.
BINARY_CLOUD_TYPES: tuple[str, ...] = (*LAS_TYPES, "npy", "npz", "ply")


def is_binary_cloud(data: bytes, fmt: str) -> bool:
    """Whether a file of type ``fmt`` is a cloud read without parsing text: NPY, NPZ,
    LAS, LAZ, or a binary PLY (its header read to tell)."""
    if fmt != "ply":
        return fmt in BINARY_CLOUD_TYPES
    try:
        return read_ply_header(data).binary
    except MeshFormatError:
        return False


def _parse(fmt: str, data: bytes, limits: ReadLimits) -> tuple[Rows, Rows | None]:
    """A file's points (and normals) as read: views in the file's dtype for binary
    clouds, float64 arrays otherwise."""
    if fmt == "npy":
        return _rows_npy(data, limits)
    if fmt == "npz":
        return _rows_npz(data, limits)
    binary = is_binary_cloud(data, fmt)
    if not binary:
        limits = limits.for_text()
    mesh_limits = limits.for_points()  # a mesh file's vertices are the points
    if fmt == "ply":  # a binary cloud's vertices: max_points, not the mesh vertex limit
        try:
            return read_ply_vertex_columns(
                data, replace(mesh_limits, max_vertices=limits.max_points) if binary
                else mesh_limits)
        except TooLargeError as error:
            if error.what != "vertices":
                raise
            raise TooLargeError(f"PLY: the file has {error.count} points or more; the "
                                f"limit is {error.limit}", what="points", count=error.count,
                                limit=error.limit) from None
    if fmt == "obj":
        parsed_obj = parse_obj(data, mesh_limits)
        same = len(parsed_obj.normals) == len(parsed_obj.vertices)
        return parsed_obj.vertices, parsed_obj.normals if same else None
    if fmt in _TEXT_TYPES:
        return parse_xyz(data, fmt.upper(), limits)

    return load_mesh(data, file_type=fmt, limits=mesh_limits).vertices, None


def _count(rows: Rows) -> int:
    return len(rows[0]) if isinstance(rows, tuple) else len(rows)


def _stacked(rows: Rows) -> np.ndarray:
    """(N, 3) rows: an array as it is, three columns side by side (a strided view
    when they are adjacent fields of one record, else a copy)."""
    if not isinstance(rows, tuple):
        return rows
    first = rows[0]
    same = all(c.dtype == first.dtype and c.base is first.base and c.strides == first.strides
               for c in rows)
    if same and first.base is not None:
        step = first.dtype.itemsize
        base = rows[0].__array_interface__["data"][0]
        if all(c.__array_interface__["data"][0] == base + i * step for i, c in enumerate(rows)):
            return np.lib.stride_tricks.as_strided(first, shape=(len(first), 3),
                                                   strides=(first.strides[0], step),
                                                   writeable=False)
    return np.stack(rows, axis=1)


def _check_finite(rows: np.ndarray, label: str, what: str) -> None:
    """Raise :class:`NonFiniteError` when a row has a NaN or infinite value (every row
    is checked, a block at a time)."""
    if rows.dtype.kind != "f":
        return
    block = 1 << 20
    for start in range(0, len(rows), block):
        finite = np.isfinite(rows[start:start + block]).all(axis=1)
        if not finite.all():
            bad = start + int(np.flatnonzero(~finite)[0])
            n_bad = sum(int((~np.isfinite(rows[s:s + block]).all(axis=1)).sum())
                        for s in range(start, len(rows), block))
            raise NonFiniteError(f"{label}: {what} {bad} has a NaN or infinite coordinate "
                                 f"({n_bad} {what} rows are not finite)")


@dataclass(frozen=True)
class PointsRead:
    """A point cloud as read, maybe reduced (:func:`read_points`).

    Attributes
    ----------
    points : (M, 3) float64
        Finite, ``M >= 1``.
    normals : (M, 3) float64 or None
        The normals of the same rows, as stored.
    count : int
        Points in the file (``M`` unless the cloud was reduced).
    """

    points: FloatArray
    normals: FloatArray | None
    count: int

    @property
    def reduced(self) -> bool:
        """The file had more points than were kept."""
        return self.count > len(self.points)


def read_points(
    path_or_bytes: str | os.PathLike[str] | bytes | BinaryIO,
    file_type: str | None = None,
    limits: ReadLimits | None = None,
    *,
    keep: int | None = None,
    seed: int = REDUCE_SEED,
) -> PointsRead:
    """Read a point cloud, reduced to at most ``keep`` points.

    A binary cloud (binary PLY, NPY, NPZ) is read as views over the file's bytes in its
    own dtype; only the kept rows are converted to float64
    (:func:`spacemesh.io.reduce.reduce_cloud`), so reading takes the file's bytes (an
    NPZ member once inflated) plus about one byte a row, whatever ``keep``. Every row is
    checked to be finite, kept or not. ``limits.max_points`` applies to binary clouds,
    the smaller of it and ``limits.max_text_points`` to every other format.

    Parameters
    ----------
    path_or_bytes : path, bytes or binary file object
    file_type : str, optional
        Overrides the extension (as :func:`load_points`).
    limits : ReadLimits, optional
        Counts and decoded sizes allowed, checked while reading (default: none).
    keep : int, optional
        Most points returned (None: all); a larger cloud gives a seeded uniform random
        subset of its rows (:func:`spacemesh.io.reduce.reduction_indices`).
    seed : int
        Seed of the subset.

    Returns
    -------
    PointsRead

    Raises
    ------
    MeshFormatError, TooLargeError, UnsupportedFormatError
        As :func:`load_points`; :class:`~spacemesh.io.errors.NonFiniteError` (a
        MeshFormatError) for a NaN or infinite value in any row.
    """
    data, extension, _ = read_source(path_or_bytes)
    fmt = resolve_file_type(file_type, extension, data, SUPPORTED_POINTS_READ, "point cloud")
    label = fmt.upper()
    require_nonempty(data, label)
    if fmt in LAS_TYPES:  # reduced while it is read, a block at a time
        las_points, count = read_las(data, label, limits, keep=keep, seed=seed)
        return PointsRead(check_vertices(las_points, label, what="point"), None, count)
    try:
        raw_points, raw_normals = _parse(fmt, data, limits or UNLIMITED)
        rows = _stacked(raw_points)
        normal_rows = None if raw_normals is None else _stacked(raw_normals)
    except MeshFormatError:
        raise
    except (ValueError, IndexError, KeyError, TypeError, OverflowError) as exc:
        raise MeshFormatError(f"{label}: could not read the file ({exc})") from None
    count = _count(rows)
    if count == 0:
        raise MeshFormatError(f"{label}: the file contains no point positions")
    if normal_rows is not None and len(normal_rows) != count:
        raise MeshFormatError(f"{label}: {len(normal_rows)} normals for {count} points")
    _check_finite(rows, label, "point")
    if normal_rows is not None:
        _check_finite(normal_rows, label, "normal")
    points, normals = reduce_cloud(rows, normal_rows, keep, seed=seed)
    return PointsRead(check_vertices(points, label, what="point"), normals, count)


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
    read = read_points(path_or_bytes, file_type, limits)
    return read.points, read.normals


__all__ = ["BINARY_CLOUD_TYPES", "SUPPORTED_POINTS_READ", "PointsRead", "is_binary_cloud",
           "load_points", "parse_npy", "parse_npz", "parse_xyz", "read_points"]
