"""Object File Format (OFF), ASCII: polygons read and written as they are.

Read: the ``OFF``, ``COFF``, ``NOFF``, ``CNOFF``, ``STOFF`` and ``4OFF`` headers (or
none), counts on the header line or the next one, ``#`` comments, extra vertex
columns (colours, normals, texture coordinates) and face colours ignored, and faces
wrapped over several lines. Each vertex and face is expected to start a new line;
when that reading does not fit the counts, the file is read again as one plain
token stream (several records per line).
"""

from __future__ import annotations

import itertools
import re
from array import array
from collections.abc import Iterator, Sequence
from itertools import pairwise
from typing import Any

import numpy as np

from spacemesh.io.errors import (
    MeshFormatError,
    check_face_indices,
    check_vertices,
    decode_text,
    require_nonempty,
)
from spacemesh.io.limits import UNLIMITED, ReadLimits, iter_lines
from spacemesh.mesh import PolygonMesh

_HEADER = re.compile(r"^(ST)?(C)?(N)?(4)?(n)?OFF$")


def _int(token: str, what: str) -> int:
    try:
        return int(token)
    except ValueError:
        raise MeshFormatError(f"OFF: {what} is not a whole number: '{token}'") from None


class _EndOfData(Exception):
    """The token lines ran out in the middle of a record."""


class _Lines(Sequence[list[str]]):
    """The non-empty lines of a file, comments cut, kept as text and split when read.

    A line's tokens are made only when a record reads it (the last line split is
    cached), so the file is held as one string per line rather than one string per
    token: about a quarter of the memory.
    """

    def __init__(self, lines: list[str]) -> None:
        self._lines = lines
        self._at = -1
        self._tokens: list[str] = []

    def __len__(self) -> int:
        return len(self._lines)

    def __getitem__(self, index: int) -> list[str]:  # type: ignore[override]
        if index != self._at:
            self._at, self._tokens = index, self._lines[index].split()
        return self._tokens


class _Cursor:
    """A position in a list of token lines; records may wrap onto following lines."""

    def __init__(self, lines: Sequence[list[str]], line: int = 0, token: int = 0) -> None:
        self.lines, self.line, self.token = lines, line, token

    def take(self, count: int) -> list[str]:
        """The next ``count`` tokens, continuing onto following lines as needed."""
        out: list[str] = []
        while len(out) < count:
            if self.line >= len(self.lines):
                raise _EndOfData
            row = self.lines[self.line]
            chunk = row[self.token : self.token + count - len(out)]
            out.extend(chunk)
            self.token += len(chunk)
            if self.token >= len(row):
                self.line, self.token = self.line + 1, 0
        return out

    def record(self, count: int, by_line: bool) -> list[str]:
        """The next record of ``count`` tokens; by line, the rest of its line is skipped."""
        if by_line and self.token == 0 and self.line < len(self.lines):
            row = self.lines[self.line]
            if len(row) >= count:  # the usual case: the record fits on its line
                self.line += 1
                return row[:count]
        out = self.take(count)
        if by_line:
            self.end_record()
        return out

    def end_record(self) -> None:
        """Skip what is left of the current line (vertex or face colours)."""
        if self.token:
            self.line, self.token = self.line + 1, 0


def _read_header(lines: Sequence[list[str]]) -> tuple[str, int, int, _Cursor]:
    """The header keyword, the vertex and face counts, and where the data starts."""
    first = lines[0]
    keyword = ""
    cursor = _Cursor(lines)
    if _HEADER.match(first[0]):
        keyword = first[0]
        cursor.token = 1
        if len(first) == 1:
            cursor.end_record()
    elif not first[0].lstrip("+-").isdigit():
        raise MeshFormatError(
            f"OFF: the file does not start with an OFF header (found '{first[0][:20]}')"
        )
    if "n" in keyword or "4" in keyword:
        raise MeshFormatError(f"OFF: the '{keyword}' variant (not 3D) is not supported")
    row = lines[cursor.line] if cursor.line < len(lines) else []
    counts = row[cursor.token :]
    if len(counts) < 2:
        raise MeshFormatError("OFF: the header must give the vertex and face counts")
    n_vertices = _int(counts[0], "the vertex count")
    n_faces = _int(counts[1], "the face count")
    if n_vertices < 0 or n_faces < 0:
        raise MeshFormatError("OFF: the vertex and face counts must not be negative")
    return keyword, n_vertices, n_faces, _Cursor(lines, cursor.line + 1)


class _Numbers:
    """Tokens converted as they are read into a compact array (8 bytes each); the first
    token that does not convert is remembered and reported once all are read."""

    def __init__(self, kind: str) -> None:
        self.values: array[Any] = array(kind)
        self.convert = float if kind == "d" else int
        self.bad: tuple[int, str] | None = None  # (position, token)
        self.overflow = False

    def extend(self, tokens: list[str]) -> None:
        for token in tokens:
            try:
                self.values.append(self.convert(token))
            except ValueError:
                if self.bad is None:
                    self.bad = (len(self.values), token)
                self.values.append(0)
            except OverflowError:
                self.overflow = True
                self.values.append(0)


def _read_faces(cursor: _Cursor, n_faces: int, by_line: bool) -> tuple[np.ndarray, np.ndarray]:
    indices = _Numbers("q")
    sizes = array("q")
    f = 0
    try:
        for f in range(n_faces):
            if by_line and cursor.token == 0 and cursor.line < len(cursor.lines):
                row = cursor.lines[cursor.line]
                size = _int(row[0], f"the size of face {f}")
                if 0 < size < len(row):  # the usual case: the face fits on its line
                    indices.extend(row[1 : size + 1])
                    sizes.append(size)
                    cursor.line += 1
                    continue
            size = _int(cursor.take(1)[0], f"the size of face {f}")
            if size < 1:
                raise MeshFormatError(f"OFF: face {f} has {size} vertices")
            indices.extend(cursor.take(size))
            sizes.append(size)
            if by_line:
                cursor.end_record()
    except _EndOfData:
        raise MeshFormatError(
            f"OFF: file ends early: expected {n_faces} faces, found {f}"
        ) from None
    if indices.bad is not None:
        raise MeshFormatError(f"OFF: a face index is not a whole number: '{indices.bad[1]}'")
    if indices.overflow:
        raise MeshFormatError("OFF: a face index is too large")
    flat = np.frombuffer(indices.values, dtype=np.int64).copy()
    offsets = np.concatenate([[0], np.cumsum(np.frombuffer(sizes, dtype=np.int64))]).astype(
        np.int64
    )
    return flat, offsets


def _parse(lines: Sequence[list[str]], by_line: bool) -> PolygonMesh:
    keyword, n_vertices, n_faces, cursor = _read_header(lines)
    width = 3
    if not by_line:  # one token stream: vertex records have a fixed width
        if "C" in keyword:
            raise MeshFormatError("OFF: coloured vertices must each start a new line")
        width = 3 + 3 * ("N" in keyword) + 2 * ("ST" in keyword)
    coordinates = _Numbers("d")
    v = 0
    try:
        for v in range(n_vertices):  # noqa: B007 - v is reported on error
            coordinates.extend(cursor.record(width, by_line)[:3])
    except _EndOfData:
        raise MeshFormatError(
            f"OFF: file ends early: expected {n_vertices} vertices, found {v}"
        ) from None
    if coordinates.bad is not None:
        at, token = coordinates.bad
        raise MeshFormatError(
            f"OFF: vertex {at // 3} has a coordinate that is not a number: '{token}'"
        )
    positions = np.frombuffer(coordinates.values, dtype=np.float64).reshape(n_vertices, 3)
    vertices = check_vertices(positions.copy(), "OFF")
    flat, offsets = _read_faces(cursor, n_faces, by_line)
    check_face_indices(flat, offsets, n_vertices, "OFF")
    return PolygonMesh(vertices, flat, offsets)


def _comment_free_lines(text: str) -> Iterator[str]:
    """The lines of ``text`` with comments cut, those with a token, read one at a time."""
    for raw in iter_lines(text):
        line = raw.split("#", 1)[0]
        if not line.isspace() and line:
            yield line


def _token_lines(text: str) -> Iterator[list[str]]:
    """The non-empty token lines of ``text``, comments cut, read one at a time."""
    for raw in iter_lines(text):
        tokens = raw.split("#", 1)[0].split()
        if tokens:
            yield tokens


def _check_header(text: str, size: int, limits: ReadLimits) -> None:
    """Refuse declared counts over ``limits`` or more than ``size`` bytes can hold
    (a vertex takes at least 6 bytes, ``"0 0 0\\n"``, a face at least 4, ``"1 0\\n"``)."""
    head = list(itertools.islice(_token_lines(text), 2))
    if not head:
        raise MeshFormatError("OFF: the file holds only comments")
    _, n_vertices, n_faces, _ = _read_header(head)
    limits.check_vertices("OFF", n_vertices)
    limits.check_faces("OFF", n_faces)
    needed = 6 * n_vertices + 4 * n_faces - 1
    if needed > size:
        raise MeshFormatError(
            f"OFF: file ends early: the header declares {n_vertices} vertices and {n_faces} "
            f"faces, which need at least {needed} bytes; the file holds {size}"
        )


def load_off(data: bytes, limits: ReadLimits | None = None) -> PolygonMesh:
    """Read an OFF file's polygons.

    The header's counts are checked against ``limits`` and the bytes present before
    the records are read.

    Parameters
    ----------
    data : bytes
        The file's content.
    limits : ReadLimits, optional

    Returns
    -------
    PolygonMesh
    """
    require_nonempty(data, "OFF")
    text = decode_text(data, "OFF")
    _check_header(text, len(data), limits or UNLIMITED)
    lines = _Lines(list(_comment_free_lines(text)))
    try:
        return _parse(lines, by_line=True)
    except MeshFormatError as by_line_error:
        try:
            return _parse(lines, by_line=False)
        except MeshFormatError:
            raise by_line_error from None


def export_off(mesh: PolygonMesh) -> bytes:
    """Write a mesh as OFF text, polygons kept, positions written exactly.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    bytes
    """
    lines = ["OFF", f"{mesh.n_vertices} {mesh.n_faces} 0"]  # edge count: unused by readers
    lines.extend(f"{x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist())
    indices = mesh.face_indices.tolist()
    offsets = mesh.face_offsets.tolist()
    lines.extend(f"{b - a} " + " ".join(map(str, indices[a:b])) for a, b in pairwise(offsets))
    return ("\n".join(lines) + "\n").encode("ascii")


__all__ = ["export_off", "load_off"]
