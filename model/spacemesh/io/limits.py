"""How much a reader may take from a file: counts and decoded sizes, checked while reading.

Every reader takes an optional :class:`ReadLimits`. A reader checks each count a file
declares (a PLY element count, an OFF header, an ``.npy`` shape, a zip member's
uncompressed size, a glTF accessor count or buffer length, a binary STL triangle count)
against it *before* it allocates for that count, and counts text rows as it reads them,
stopping at the limit instead of reading everything. Past a limit it raises
:class:`~spacemesh.io.errors.TooLargeError`. Without limits (the default, as in the
command line reading local files) nothing is refused for its size.

The service builds its limits from its settings (``--max-points``,
``--max-mesh-vertices``, ``--max-mesh-faces``, ``--max-upload-bytes``), so a hostile
upload costs at most a known multiple of those, whatever it declares.

Examples
--------
>>> from spacemesh.io.limits import ReadLimits
>>> limits = ReadLimits(max_points=200_000, max_vertices=10**6, max_faces=2 * 10**6)
>>> limits.check_points("XYZ", 300_000)
Traceback (most recent call last):
...
spacemesh.io.errors.TooLargeError: XYZ: the file has 300000 points or more; the limit is 200000
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

from spacemesh.io.errors import MeshFormatError, TooLargeError

#: Corners per face allowed on average (``max_corners = 4 * max_faces``: quads).
CORNERS_PER_FACE = 4
#: JSON values (numbers, strings, containers) allowed per point or vertex: a point and
#: its normal as ``[x, y, z]`` lists are 8 values.
JSON_VALUES_PER_POINT = 8
#: JSON values allowed besides the points (options, a glTF document's structure).
JSON_VALUES_SLACK = 4096

#: Line breaks of ``str.splitlines`` other than ``\n``.
_OTHER_BREAKS = re.compile("[\r\v\f\x1c\x1d\x1e\x85\u2028\u2029]")


@dataclass(frozen=True)
class ReadLimits:
    """The most a reader may take from one file; None: unlimited.

    Attributes
    ----------
    max_points : int, optional
        Rows of a point cloud (text rows, ``.npy`` rows, PLY or mesh vertices read as
        points).
    max_vertices : int, optional
        Vertices of a mesh (PLY, OBJ, OFF, glTF/GLB; STL corners / 3 welded).
    max_faces : int, optional
        Faces of a mesh (triangles for STL and glTF/GLB); face corners are limited to
        ``4 * max_faces``.
    max_bytes : int, optional
        Decoded bytes: a zip member's uncompressed size, a base64 glTF buffer, a JSON
        document.
    max_text_points : int, optional
        Rows of a point cloud parsed from text or read from a mesh format (anything but
        binary PLY, NPY and NPZ, whose rows are views over the file's bytes): the
        smaller of this and ``max_points`` applies to them (:meth:`for_text`).
    """

    max_points: int | None = None
    max_vertices: int | None = None
    max_faces: int | None = None
    max_bytes: int | None = None
    max_text_points: int | None = None

    def for_points(self) -> ReadLimits:
        """The limits for a mesh file read as a point cloud: its vertices are points."""
        vertices = _smallest(self.max_vertices, self.max_points)
        return replace(self, max_vertices=vertices)

    def for_text(self) -> ReadLimits:
        """The limits for a point cloud parsed from text or a mesh format: ``max_points``
        lowered to ``max_text_points``."""
        return replace(self, max_points=_smallest(self.max_points, self.max_text_points))

    @property
    def max_corners(self) -> int | None:
        """Face corners allowed in all (``CORNERS_PER_FACE`` per allowed face)."""
        return None if self.max_faces is None else CORNERS_PER_FACE * self.max_faces

    @property
    def max_json_values(self) -> int | None:
        """JSON values allowed in a document (``JSON_VALUES_PER_POINT`` per point)."""
        rows = _largest(self.max_points, self.max_vertices)
        return None if rows is None else JSON_VALUES_PER_POINT * rows + JSON_VALUES_SLACK

    # ------------------------------------------------------------------ checks
    def check_points(self, fmt: str, count: int) -> None:
        """Raise :class:`TooLargeError` when ``count`` points exceed ``max_points``."""
        _check(fmt, "points", count, self.max_points)

    def check_vertices(self, fmt: str, count: int) -> None:
        """Raise :class:`TooLargeError` when ``count`` vertices exceed ``max_vertices``."""
        _check(fmt, "vertices", count, self.max_vertices)

    def check_faces(self, fmt: str, count: int) -> None:
        """Raise :class:`TooLargeError` when ``count`` faces exceed ``max_faces``."""
        _check(fmt, "faces", count, self.max_faces)

    def check_corners(self, fmt: str, count: int) -> None:
        """Raise :class:`TooLargeError` when ``count`` face corners exceed ``max_corners``."""
        _check(fmt, "face corners", count, self.max_corners, what="corners")

    def check_rows(self, fmt: str, noun: str, count: int) -> None:
        """Raise :class:`TooLargeError` when ``count`` rows of another kind (a PLY element
        other than vertex and face) exceed the larger of ``max_vertices`` and ``max_faces``."""
        _check(fmt, noun, count, _largest(self.max_vertices, self.max_faces), what="rows")

    def check_bytes(self, fmt: str, count: int, what: str = "decoded data") -> None:
        """Raise :class:`TooLargeError` when ``count`` bytes exceed ``max_bytes``."""
        _check(fmt, f"bytes of {what}", count, self.max_bytes, what="bytes")


#: No limits (the readers' default).
UNLIMITED = ReadLimits()


def _smallest(*values: int | None) -> int | None:
    given = [v for v in values if v is not None]
    return min(given) if given else None


def _largest(*values: int | None) -> int | None:
    given = [v for v in values if v is not None]
    return max(given) if given else None


def _check(fmt: str, noun: str, count: int, limit: int | None, what: str | None = None) -> None:
    if limit is not None and count > limit:
        raise TooLargeError(
            f"{fmt}: the file has {count} {noun} or more; the limit is {limit}",
            what=what or noun,
            count=int(count),
            limit=int(limit),
        )


def iter_lines(text: str) -> Iterator[str]:
    """The lines of ``text`` one at a time (as ``str.splitlines``, without the list).

    Parameters
    ----------
    text : str

    Yields
    ------
    str
        Each line without its line break.
    """
    start, size = 0, len(text)
    while start < size:
        end = text.find("\n", start)
        if end < 0:
            end = size
        chunk = text[start:end]
        start = end + 1
        if _OTHER_BREAKS.search(chunk) is None:
            yield chunk
        else:
            yield from chunk.splitlines() or [""]


def load_json(data: bytes | bytearray | str, fmt: str, limits: ReadLimits | None = None) -> Any:
    """Parse JSON, its length and number of values checked before parsing.

    The values are counted from the separators and brackets (``,`` ``[`` ``{``, an upper
    bound, strings included), so a document that would become millions of Python
    objects is refused before any is made. Nesting deeper than Python's recursion
    limit is a :class:`MeshFormatError`.

    Parameters
    ----------
    data : bytes or str
    fmt : str
        The format's name for messages.
    limits : ReadLimits, optional

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    TooLargeError
        Longer than ``max_bytes`` or more values than ``max_json_values``.
    MeshFormatError
        Not valid JSON (or not UTF-8), or nested too deeply.
    """
    limits = limits or UNLIMITED
    limits.check_bytes(fmt, len(data), "JSON")
    most = limits.max_json_values
    if most is not None:
        if isinstance(data, str):
            count = data.count(",") + data.count("[") + data.count("{")
        else:
            count = data.count(b",") + data.count(b"[") + data.count(b"{")
        _check(fmt, "JSON values", count, most, what="values")
    try:
        if isinstance(data, bytes | bytearray):
            data = bytes(data).decode("utf-8-sig")
        return json.loads(data)
    except RecursionError:
        raise MeshFormatError(f"{fmt}: the JSON is nested too deeply") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise MeshFormatError(f"{fmt}: not valid JSON ({exc})") from None


__all__ = [
    "CORNERS_PER_FACE",
    "JSON_VALUES_PER_POINT",
    "JSON_VALUES_SLACK",
    "UNLIMITED",
    "ReadLimits",
    "iter_lines",
    "load_json",
]
