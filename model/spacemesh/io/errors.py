"""The errors raised by the readers, and the small checks that raise them.

Every malformed input raises :class:`MeshFormatError` (a ``ValueError``) with a
message meant for the person who supplied the file, e.g.
``"OFF: face 12 refers to vertex 900 but the file has 100 vertices"``.
"""

from __future__ import annotations

import re

import numpy as np

from spacemesh.typed import FloatArray, IntArray

#: Bytes that are all ASCII whitespace (what ``bytes.strip`` removes).
_BLANK = re.compile(rb"[ \t\n\r\x0b\x0c]*")


class MeshFormatError(ValueError):
    """A mesh or point-cloud file that cannot be read: malformed, truncated or empty."""


class UnsupportedFormatError(MeshFormatError):
    """A file type (extension) that no reader or writer handles."""


class NonFiniteError(MeshFormatError):
    """A well-formed file whose coordinates include NaN or infinity."""


class TooLargeError(MeshFormatError):
    """A file that declares or holds more than a :class:`~spacemesh.io.limits.ReadLimits`
    allows, refused before the reader allocates for it.

    Attributes
    ----------
    what : str
        What is counted: ``"points"``, ``"vertices"``, ``"faces"``, ``"corners"``,
        ``"bytes"`` or ``"values"`` (JSON numbers, strings and containers).
    count : int
        How many the file declares or holds (at least; readers stop counting at the
        limit).
    limit : int
        The most allowed.
    """

    def __init__(self, message: str, *, what: str, count: int, limit: int) -> None:
        super().__init__(message)
        self.what, self.count, self.limit = what, count, limit


def read_error_kind(error: MeshFormatError) -> str:
    """The problem kind (the service's slug) of a reader's error: ``too-many-points``
    (a point cloud past its row limit) or ``payload-too-large`` (any other limit),
    ``unsupported-format``, ``non-finite``, else ``malformed-input``."""
    if isinstance(error, TooLargeError):
        return "too-many-points" if error.what == "points" else "payload-too-large"
    if isinstance(error, UnsupportedFormatError):
        return "unsupported-format"
    if isinstance(error, NonFiniteError):
        return "non-finite"
    return "malformed-input"


def decode_text(data: bytes, fmt: str) -> str:
    """Decode a text format as UTF-8 (tolerating a BOM), falling back to Latin-1.

    Parameters
    ----------
    data : bytes
        The file's content.
    fmt : str
        The format's name for messages, e.g. ``"OBJ"``.

    Returns
    -------
    str
    """
    if b"\x00" in data[:4096]:
        raise MeshFormatError(f"{fmt}: the file is binary, not {fmt} text")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def is_blank(data: bytes | str) -> bool:
    """Whether ``data`` holds nothing but whitespace (as ``not data.strip()``, without
    copying a large file: the scan stops at its first other character)."""
    if isinstance(data, str):
        return not data.strip()
    return _BLANK.fullmatch(data) is not None


def require_nonempty(data: bytes, fmt: str) -> None:
    """Raise when the file holds nothing but whitespace."""
    if is_blank(data):
        raise MeshFormatError(f"{fmt}: the file is empty")


def check_vertices(vertices: FloatArray, fmt: str, what: str = "vertex") -> FloatArray:
    """Require at least one vertex and only finite coordinates.

    Parameters
    ----------
    vertices : (V, 3) float
        Parsed positions.
    fmt : str
        The format's name for messages.
    what : str
        What a row is called in messages ("vertex", "point").

    Returns
    -------
    (V, 3) float64
        The same positions as float64.
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if len(vertices) == 0:
        raise MeshFormatError(f"{fmt}: the file contains no {what} positions")
    finite = np.isfinite(vertices).all(axis=1)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        n_bad = int((~finite).sum())
        raise NonFiniteError(
            f"{fmt}: {what} {bad} has a NaN or infinite coordinate "
            f"({n_bad} {what} rows are not finite)"
        )
    return vertices


def check_face_indices(
    indices: IntArray, offsets: IntArray, n_vertices: int, fmt: str, base: int = 0
) -> None:
    """Raise when a face refers to a vertex outside ``[0, n_vertices)``.

    Parameters
    ----------
    indices : (S,) int64
        Flat face indices, already 0-based.
    offsets : (F + 1,) int64
        CSR face offsets.
    n_vertices : int
        Number of vertices in the file.
    fmt : str
        The format's name for messages.
    base : int
        Added to the index in the message (1 for OBJ, whose files count from 1).
    """
    bad = (indices < 0) | (indices >= n_vertices)
    if bad.any():
        corner = int(np.flatnonzero(bad)[0])
        face = int(np.searchsorted(offsets, corner, side="right") - 1)
        raise MeshFormatError(
            f"{fmt}: face {face} refers to vertex {int(indices[corner]) + base} "
            f"but the file has {n_vertices} vertices"
        )


__all__ = [
    "MeshFormatError",
    "NonFiniteError",
    "TooLargeError",
    "UnsupportedFormatError",
    "check_face_indices",
    "check_vertices",
    "decode_text",
    "is_blank",
    "require_nonempty",
]
