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
import zipfile
from typing import BinaryIO

import numpy as np

from spacemesh.io.errors import MeshFormatError, check_vertices, decode_text, require_nonempty
from spacemesh.io.obj import parse_obj
from spacemesh.io.ply import parse_ply
from spacemesh.typed import FloatArray

_TEXT_TYPES = ("csv", "pts", "txt", "xyz")
#: File types :func:`load_points` reads.
SUPPORTED_POINTS_READ: tuple[str, ...] = tuple(
    sorted({"npy", "npz", "obj", "ply", "off", "stl", "glb", "gltf", *_TEXT_TYPES})
)
_SEPARATORS = re.compile(r"[\s,;]+")


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


def parse_xyz(data: bytes, fmt: str = "XYZ") -> tuple[FloatArray, FloatArray | None]:
    """Parse text columns: ``x y z`` or ``x y z nx ny nz`` per line.

    Parameters
    ----------
    data : bytes
        The file's content.
    fmt : str
        The format's name for messages.

    Returns
    -------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    require_nonempty(data, fmt)
    text = decode_text(data, fmt)
    rows: list[list[str]] = []
    numbers: list[int] = []
    first = True
    for number, raw in enumerate(text.splitlines(), start=1):
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


def parse_npy(data: bytes) -> tuple[FloatArray, FloatArray | None]:
    """Parse a ``.npy`` array of shape (N, 3) or (N, 6).

    Parameters
    ----------
    data : bytes

    Returns
    -------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    try:
        array = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise MeshFormatError(f"NPY: not a readable NumPy array file ({exc})") from None
    if not isinstance(array, np.ndarray):
        raise MeshFormatError("NPY: the file does not hold a single array")
    return _split_normals(array, "NPY")


def parse_npz(data: bytes) -> tuple[FloatArray, FloatArray | None]:
    """Parse a ``.npz`` archive: ``points`` (+ ``normals``) or one array.

    Parameters
    ----------
    data : bytes

    Returns
    -------
    points : (N, 3) float64
    normals : (N, 3) float64 or None
    """
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise MeshFormatError(f"NPZ: not a readable NumPy archive ({exc})") from None
    if "points" in arrays:
        points, normals = _split_normals(arrays["points"], "NPZ")
        if "normals" in arrays:
            normals, _ = _split_normals(np.asarray(arrays["normals"]), "NPZ normals")
            if normals.shape != points.shape:
                raise MeshFormatError(f"NPZ: {len(normals)} normals for {len(points)} points")
        return points, normals
    if len(arrays) == 1:
        return _split_normals(next(iter(arrays.values())), "NPZ")
    raise MeshFormatError(
        f"NPZ: expected an array named 'points' (found {', '.join(sorted(arrays)) or 'none'})"
    )


def _parse(fmt: str, data: bytes) -> tuple[FloatArray, FloatArray | None]:
    if fmt == "ply":
        parsed = parse_ply(data)
        return parsed.vertices, parsed.normals
    if fmt == "obj":
        parsed_obj = parse_obj(data)
        same = len(parsed_obj.normals) == len(parsed_obj.vertices)
        return parsed_obj.vertices, parsed_obj.normals if same else None
    if fmt == "npy":
        return parse_npy(data)
    if fmt == "npz":
        return parse_npz(data)
    if fmt in _TEXT_TYPES:
        return parse_xyz(data, fmt.upper())
    from spacemesh.io import load_mesh  # the mesh formats: their vertices

    return load_mesh(data, file_type=fmt).vertices, None


def load_points(
    path_or_bytes: str | os.PathLike[str] | bytes | BinaryIO, file_type: str | None = None
) -> tuple[FloatArray, FloatArray | None]:
    """Read a point cloud, with normals when the file has them.

    Parameters
    ----------
    path_or_bytes : path, bytes or binary file object
        The file. Bytes (an upload) are read as ``file_type`` or, when it is not
        given, as whatever their content looks like.
    file_type : str, optional
        ``"ply"``, ``".xyz"``, ``"scan.npz"``...; overrides the extension.

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
    UnsupportedFormatError
        The file type is not one of :data:`SUPPORTED_POINTS_READ`.
    """
    from spacemesh.io import read_source, resolve_file_type

    data, extension, _ = read_source(path_or_bytes)
    fmt = resolve_file_type(file_type, extension, data, SUPPORTED_POINTS_READ, "point cloud")
    label = fmt.upper()
    require_nonempty(data, label)
    try:
        points, normals = _parse(fmt, data)
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
