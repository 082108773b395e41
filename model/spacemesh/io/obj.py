"""Wavefront OBJ: polygons read and written as they are (1-based, relative indices read).

Read: ``v`` (extra columns such as ``w`` or vertex colours ignored), ``vn`` (kept for
point clouds), ``f`` with ``i``, ``i/t``, ``i//n`` and ``i/t/n`` corners and negative
(relative) indices, ``\\`` line continuations and ``#`` comments. Texture
coordinates, materials, groups, smoothing groups, lines and points are ignored.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from spacemesh.io.errors import (
    MeshFormatError,
    check_vertices,
    decode_text,
    require_nonempty,
)
from spacemesh.io.limits import UNLIMITED, ReadLimits, iter_lines
from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray, IntArray


@dataclass(frozen=True)
class ObjData:
    """What the OBJ reader keeps from a file."""

    vertices: FloatArray  # (V, 3) float64
    normals: FloatArray  # (N, 3) float64, the ``vn`` rows (N may differ from V)
    face_indices: IntArray  # (S,) int64, 0-based
    face_offsets: IntArray  # (F + 1,) int64


def _logical_lines(text: str) -> Iterator[tuple[int, str]]:
    """Yield ``(line_number, content)`` with comments cut and continuations joined."""
    pending, start = "", 0
    for number, raw in enumerate(iter_lines(text), start=1):
        line = raw.split("#", 1)[0]
        if not pending:
            start = number
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        yield start, pending + line
        pending = ""
    if pending:
        yield start, pending


def _floats(tokens: list[str], line: int, what: str) -> list[float]:
    if len(tokens) < 3:
        raise MeshFormatError(f"OBJ: line {line}: '{what}' needs 3 coordinates")
    try:
        return [float(tokens[0]), float(tokens[1]), float(tokens[2])]
    except ValueError:
        raise MeshFormatError(
            f"OBJ: line {line}: '{what}' coordinates are not numbers: {' '.join(tokens[:3])}"
        ) from None


def parse_obj(data: bytes, limits: ReadLimits | None = None) -> ObjData:
    """Parse OBJ bytes into positions, ``vn`` normals and polygon faces.

    Lines are read one at a time; past ``limits`` (vertices, normals, faces or face
    corners) the reading stops with :class:`~spacemesh.io.errors.TooLargeError`.

    Parameters
    ----------
    data : bytes
        The file's content.
    limits : ReadLimits, optional

    Returns
    -------
    ObjData
    """
    require_nonempty(data, "OBJ")
    limits = limits or UNLIMITED
    text = decode_text(data, "OBJ")
    # compact arrays (8 bytes a number), not lists of Python objects
    vertices, normals = array("d"), array("d")  # x y z x y z ...
    indices, sizes, face_lines = array("q"), array("q"), array("q")
    for number, line in _logical_lines(text):
        tokens = line.split()
        if not tokens:
            continue
        key = tokens[0]
        if key == "v":
            limits.check_vertices("OBJ", len(vertices) // 3 + 1)
            vertices.extend(_floats(tokens[1:], number, "v"))
        elif key == "vn":
            limits.check_vertices("OBJ", len(normals) // 3 + 1)
            normals.extend(_floats(tokens[1:], number, "vn"))
        elif key == "f":
            corners = tokens[1:]
            if not corners:
                raise MeshFormatError(f"OBJ: line {number}: face has no vertices")
            limits.check_faces("OBJ", len(sizes) + 1)
            limits.check_corners("OBJ", len(indices) + len(corners))
            n_known = len(vertices) // 3
            for corner in corners:
                head = corner.split("/", 1)[0]
                try:
                    index = int(head)
                except ValueError:
                    raise MeshFormatError(
                        f"OBJ: line {number}: face corner '{corner}' is not a vertex index"
                    ) from None
                if index == 0:
                    raise MeshFormatError(
                        f"OBJ: line {number}: vertex index 0 is invalid (OBJ counts from 1)"
                    )
                if abs(index) > 2**53:
                    raise MeshFormatError(f"OBJ: line {number}: vertex index {head} is too large")
                if index < 0:
                    index += n_known + 1
                    if index < 1:
                        raise MeshFormatError(
                            f"OBJ: line {number}: relative index {head} reaches before "
                            f"the first vertex ({n_known} vertices defined so far)"
                        )
                indices.append(index - 1)
            sizes.append(len(corners))
            face_lines.append(number)
    positions = check_vertices(
        np.frombuffer(vertices, dtype=np.float64).reshape(-1, 3).copy(), "OBJ"
    )
    flat = np.frombuffer(indices, dtype=np.int64).copy()
    offsets = np.concatenate([[0], np.cumsum(np.frombuffer(sizes, dtype=np.int64))]).astype(
        np.int64
    )
    bad = flat >= len(positions)
    if bad.any():
        bad_corner = int(np.flatnonzero(bad)[0])
        face = int(np.searchsorted(offsets, bad_corner, side="right") - 1)
        raise MeshFormatError(
            f"OBJ: line {face_lines[face]}: face refers to vertex {int(flat[bad_corner]) + 1} "
            f"but the file has {len(positions)} vertices"
        )
    normal_array = np.frombuffer(normals, dtype=np.float64).reshape(-1, 3).copy()
    return ObjData(positions, normal_array, flat, offsets)


def load_obj(data: bytes, limits: ReadLimits | None = None) -> PolygonMesh:
    """Read an OBJ file's polygons.

    Parameters
    ----------
    data : bytes
        The file's content.
    limits : ReadLimits, optional
        Counts allowed (:func:`parse_obj`).

    Returns
    -------
    PolygonMesh
    """
    parsed = parse_obj(data, limits)
    return PolygonMesh(parsed.vertices, parsed.face_indices, parsed.face_offsets)


def export_obj(mesh: PolygonMesh) -> bytes:
    """Write a mesh as OBJ text, polygons kept, positions written exactly.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    bytes
    """
    lines = [f"# SpaceMesh OBJ: {mesh.n_vertices} vertices, {mesh.n_faces} faces"]
    lines.extend(f"v {x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist())
    one_based = (mesh.face_indices + 1).tolist()
    offsets = mesh.face_offsets.tolist()
    lines.extend("f " + " ".join(map(str, one_based[a:b])) for a, b in pairwise(offsets))
    return ("\n".join(lines) + "\n").encode("ascii")


__all__ = ["ObjData", "export_obj", "load_obj", "parse_obj"]
