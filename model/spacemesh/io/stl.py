"""STL, ASCII and binary: triangle soup welded at exactly coincident positions.

STL stores every triangle with its own three positions, so connectivity is recovered
by merging rows that are exactly equal (``np.unique`` on the float64 rows); nothing
is snapped within a tolerance. Binary STL is recognised by its size
(``84 + 50 * n`` bytes), even when its 80-byte header starts with ``solid``.
Written: binary, triangulated with :func:`spacemesh.primitives.triangulate_manifold`
(manifold polygon meshes give manifold triangle meshes once welded).
"""

from __future__ import annotations

import numpy as np

from spacemesh.io.errors import MeshFormatError, check_vertices, decode_text, require_nonempty
from spacemesh.io.limits import UNLIMITED, ReadLimits
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import triangulate_manifold, weld
from spacemesh.typed import FloatArray

_RECORD = np.dtype(
    [("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")]
)  # 50 bytes


def binary_count(data: bytes) -> int | None:
    """The triangle count of a binary STL whose size matches it exactly, else None."""
    if len(data) < 84:
        return None
    count = int(np.frombuffer(data, "<u4", 1, 80)[0])
    return count if len(data) == 84 + 50 * count else None


def _read_binary(data: bytes, limits: ReadLimits) -> FloatArray:
    """(3 n, 3) corner positions of a binary STL (the declared count checked first)."""
    if len(data) < 84:
        raise MeshFormatError("STL: file ends early: a binary STL has an 84-byte header")
    count = int(np.frombuffer(data, "<u4", 1, 80)[0])
    limits.check_faces("STL", count)
    if len(data) < 84 + 50 * count:
        found = (len(data) - 84) // 50
        raise MeshFormatError(
            f"STL: file ends early: expected {count} triangles, the file holds {found}"
        )
    records = np.frombuffer(data, _RECORD, count, 84)
    return records["corners"].reshape(-1, 3).astype(np.float64)


def _read_ascii(data: bytes, limits: ReadLimits) -> FloatArray:
    """(3 n, 3) corner positions of an ASCII STL (every ``vertex`` line, in order)."""
    limits.check_faces("STL", sum(data.count(w) for w in (b"endfacet", b"ENDFACET")))
    tokens = decode_text(data, "STL").split()
    lowered = [t.lower() for t in tokens]
    at = [i for i, t in enumerate(lowered) if t == "vertex"]
    if len(at) % 3:
        raise MeshFormatError(f"STL: found {len(at)} 'vertex' lines, which is not three per facet")
    n_facets = sum(1 for t in lowered if t == "facet")
    if n_facets and n_facets * 3 != len(at):
        raise MeshFormatError(f"STL: {n_facets} facets but {len(at)} vertices (each facet needs 3)")
    try:
        values = [tokens[i + k] for i in at for k in (1, 2, 3)]
        return np.array(values, dtype=np.float64).reshape(-1, 3)
    except (IndexError, ValueError):
        raise MeshFormatError("STL: a 'vertex' line does not have three numbers") from None


def load_stl(data: bytes, limits: ReadLimits | None = None) -> PolygonMesh:
    """Read an STL file (ASCII or binary) and weld exactly coincident corners.

    The triangle count (binary: declared in the header; ASCII: counted) is checked
    against ``limits.max_faces`` before the triangles are read.

    Parameters
    ----------
    data : bytes
        The file's content.
    limits : ReadLimits, optional

    Returns
    -------
    PolygonMesh
        A triangle mesh whose vertices are the distinct corner positions, in
        lexicographic order.
    """
    require_nonempty(data, "STL")
    looks_ascii = data.lstrip()[:5].lower() == b"solid" and b"\x00" not in data[:1024]
    if looks_ascii and binary_count(data) is None:
        corners = _read_ascii(data, limits or UNLIMITED)
    else:
        corners = _read_binary(data, limits or UNLIMITED)
    if len(corners) == 0:
        raise MeshFormatError("STL: the file contains no triangles")
    corners = check_vertices(corners, "STL")
    vertices, inverse = weld(corners)
    return PolygonMesh.from_faces(vertices, inverse.reshape(-1, 3))


def export_stl(mesh: PolygonMesh) -> bytes:
    """Write a mesh as binary STL (float32), faces triangulated keeping orientation.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    bytes
    """
    vertices, triangles, _ = triangulate_manifold(mesh)  # (V + C, 3), (T, 3)
    corners = vertices[triangles]  # (T, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    records = np.zeros(len(triangles), dtype=_RECORD)
    records["normal"] = normals / np.where(length > 0, length, 1.0)
    records["corners"] = corners
    header = b"SpaceMesh binary STL".ljust(80, b" ")
    return header + np.uint32(len(triangles)).astype("<u4").tobytes() + records.tobytes()


__all__ = ["binary_count", "export_stl", "load_stl", "weld"]
