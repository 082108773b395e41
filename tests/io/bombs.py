"""Small files that declare huge contents ("bombs"), one per reader, for the bounded-parser
tests and ``bench/bench_upload_memory.py``.

Each builder returns the file's bytes; ``declared`` is the count the file claims (points,
vertices or triangles). None of them holds more than a few kilobytes, except
:func:`inflating_npz`, a real archive whose member inflates to ``points * 24`` bytes.
"""

from __future__ import annotations

import base64
import io
import json
import struct
import zipfile

import numpy as np

#: What every bomb declares: a billion points, vertices or triangles.
BILLION = 10**9


def _npy_header(rows: int, columns: int = 3, dtype: str = "<f8") -> bytes:
    buffer = io.BytesIO()
    header = {"descr": dtype, "fortran_order": False, "shape": (rows, columns)}
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue()


def npy_bomb(declared: int = BILLION) -> bytes:
    """An ``.npy`` whose header declares ``(declared, 3)`` float64, with 1 KB of data."""
    return _npy_header(declared) + bytes(1024)


def npz_bomb(declared: int = BILLION, claimed_size: int | None = None) -> bytes:
    """An ``.npz`` whose ``points`` member's header declares ``(declared, 3)`` float64 and
    whose zip entry declares ``claimed_size`` uncompressed bytes (default: what the
    header needs, capped to 4 GB - 1), with 1 KB of real data."""
    data = npy_bomb(declared)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("points.npy", data)
    raw = bytearray(buffer.getvalue())
    size = claimed_size if claimed_size is not None else min(declared * 24 + 128, 2**32 - 1)
    local = raw.find(b"PK\x03\x04")
    central = raw.find(b"PK\x01\x02")
    struct.pack_into("<I", raw, local + 22, size)  # uncompressed size, local header
    struct.pack_into("<I", raw, central + 24, size)  # and central directory
    return bytes(raw)


def inflating_npz(points: int, chunk_rows: int = 1 << 16) -> bytes:
    """A real ``.npz`` of ``points`` zero points (float64) compressed with deflate: about
    a thousandth of its inflated size (the issue's 1.4 MB that inflates to 60 M points)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("points.npy", "w", force_zip64=True) as member:
            member.write(_npy_header(points))
            zeros = bytes(chunk_rows * 24)
            for start in range(0, points, chunk_rows):
                member.write(zeros[: (min(points, start + chunk_rows) - start) * 24])
    return buffer.getvalue()


def ply_bomb(declared: int = BILLION, encoding: str = "binary_little_endian") -> bytes:
    """A PLY whose header declares ``declared`` vertices and faces, with 1 KB of data."""
    header = (
        f"ply\nformat {encoding} 1.0\nelement vertex {declared}\nproperty float x\n"
        f"property float y\nproperty float z\nelement face {declared}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    body = bytes(1024) if encoding != "ascii" else b"0 0 0\n" * 170
    return header.encode() + body


def off_bomb(declared: int = BILLION) -> bytes:
    """An OFF whose header declares ``declared`` vertices and faces."""
    return f"OFF\n{declared} {declared} 0\n".encode() + b"0 0 0\n" * 170


def stl_bomb(declared: int = BILLION) -> bytes:
    """A binary STL whose header declares ``declared`` triangles, holding 20."""
    return b"bomb".ljust(80, b" ") + struct.pack("<I", declared) + bytes(50 * 20)


def obj_lines(rows: int) -> bytes:
    """An OBJ of ``rows`` vertex lines."""
    return b"v 0.5 1.5 2.5\n" * rows


def xyz_lines(rows: int) -> bytes:
    """An XYZ of ``rows`` point lines."""
    return b"0.5 1.5 2.5\n" * rows


def json_points(rows: int) -> bytes:
    """A JSON body ``{"points": [[x, y, z], ...]}`` of ``rows`` points."""
    return b'{"points": [' + b",".join([b"[0.5,1.5,2.5]"] * rows) + b"]}"


def _glb(doc: dict, binary: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\x00" * (-len(binary) % 4)
    length = 12 + 8 + len(text) + 8 + len(binary)
    return b"".join(
        [
            struct.pack("<4sII", b"glTF", 2, length),
            struct.pack("<II", len(text), 0x4E4F534A),
            text,
            struct.pack("<II", len(binary), 0x004E4942),
            binary,
        ]
    )


def _gltf_doc(declared: int, buffer: dict, view: bool = True) -> dict:
    accessor = {"componentType": 5126, "count": declared, "type": "VEC3"}
    if view:
        accessor["bufferView"] = 0
    return {
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 0}]}],
        "accessors": [accessor],
        "bufferViews": [{"buffer": 0, "byteLength": declared * 12}],
        "buffers": [buffer],
    }


def glb_bomb(declared: int = BILLION, view: bool = True) -> bytes:
    """A GLB whose POSITION accessor declares ``declared`` vertices (in a buffer that
    declares ``12 * declared`` bytes, or, with ``view=False``, as zeros without one),
    holding 1 KB."""
    return _glb(_gltf_doc(declared, {"byteLength": declared * 12}, view), bytes(1024))


def gltf_bomb(declared: int = BILLION) -> bytes:
    """A JSON glTF whose embedded base64 buffer and accessor declare ``declared`` vertices."""
    uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(1024)).decode()
    return json.dumps(_gltf_doc(declared, {"byteLength": declared * 12, "uri": uri})).encode()


#: Reader name -> (file type, bytes) of a ~1 KB file declaring a billion rows.
BOMBS = {
    "npy": ("npy", npy_bomb()),
    "npz": ("npz", npz_bomb()),
    "npz-header": ("npz", npz_bomb(claimed_size=4096)),
    "ply-binary": ("ply", ply_bomb()),
    "ply-ascii": ("ply", ply_bomb(encoding="ascii")),
    "off": ("off", off_bomb()),
    "stl": ("stl", stl_bomb()),
    "glb": ("glb", glb_bomb()),
    "glb-no-view": ("glb", glb_bomb(view=False)),
    "gltf": ("gltf", gltf_bomb()),
}
