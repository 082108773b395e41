"""LAS and LAZ point clouds (ASPRS LAS 1.0-1.4; LAZ is its compressed form), with laspy
(BSD-2-Clause) and its lazrs backend (MIT) for LAZ.

Only the positions are read: a point's X, Y and Z are integers, scaled and offset by the
header (``x = X * scale_x + offset_x``). LAS has no normals. The header's point count is
checked against the limits before any point is read, and the points are read in blocks
of :data:`CHUNK_POINTS`, each block keeping only the rows the cloud is reduced to
(:func:`spacemesh.io.reduce.reduction_indices`), so reading takes the file's bytes, one
block of records and the kept rows, whatever the count: a 10-million-point LAZ is never
decompressed whole.

numpy and laspy only (imported when a file is read).
"""

from __future__ import annotations

import io
import struct

import numpy as np

from spacemesh.io.errors import MeshFormatError
from spacemesh.io.limits import UNLIMITED, ReadLimits
from spacemesh.io.reduce import REDUCE_SEED, reduction_indices
from spacemesh.typed import FloatArray

#: Points decoded per block (about 30 MB of records for LAS point format 3).
CHUNK_POINTS = 1_000_000
#: The first bytes of every LAS and LAZ file.
LAS_MAGIC = b"LASF"
#: The file types :func:`read_las` reads (one reader: the header says which).
LAS_TYPES: tuple[str, ...] = ("las", "laz")


#: What laspy (and its LAZ backend) raise on malformed bytes, besides laspy's own
#: ``LaspyException``.
_LAS_ERRORS = (ValueError, OSError, EOFError, KeyError, IndexError, TypeError,
               RuntimeError, OverflowError, struct.error)


def _unreadable(error: BaseException) -> bool:
    """Whether ``error`` says the bytes are not a readable LAS/LAZ file: laspy's
    ``LaspyException``, one of :data:`_LAS_ERRORS`, or a panic of the Rust LAZ decoder
    (pyo3's ``PanicException`` derives from BaseException, so that ``except Exception``
    would let it through)."""
    import laspy

    return (isinstance(error, (laspy.errors.LaspyException, *_LAS_ERRORS))
            or type(error).__name__ == "PanicException")


#: Bytes of the LAS 1.0-1.2 public header block; a variable length record's header; an
#: extended one's (LAS 1.4).
HEADER_BYTES, VLR_HEADER_BYTES, EVLR_HEADER_BYTES = 227, 54, 60
#: Bytes of the LAS 1.4 public header block (with the extended records' place and count).
HEADER_BYTES_14 = 375
#: The compressed point formats of LAZ set this bit of the format id.
COMPRESSED_BIT = 0x80
#: The variable length record that describes a LAZ file's compression (its chunk size is
#: the 32-bit number 12 bytes into its data; all ones: chunks of any size).
LASZIP_RECORD = (b"laszip encoded", 22204)
VARIABLE_CHUNKS = 0xFFFFFFFF


def check_header(data: bytes, label: str = "LAS") -> None:
    """Refuse a LAS/LAZ header whose counts the file cannot hold, before laspy reads it
    (laspy reads as many variable length records as the header says, one empty record
    at a time past the end: a count of four billion would take hours).

    Parameters
    ----------
    data : bytes
        The file's content.
    label : str
        The format's name for messages.

    Raises
    ------
    MeshFormatError
        Too short for its header; the point data starts past the end; more variable
        length records than fit before the point data, or extended ones than fit after
        their start; an uncompressed file shorter than its points.
    """
    if len(data) < HEADER_BYTES:
        raise MeshFormatError(f"{label}: {len(data)} bytes, shorter than a LAS header "
                              f"({HEADER_BYTES})")
    header_size, point_start, n_vlrs = struct.unpack_from("<HII", data, 94)
    format_id, record_size, legacy_count = struct.unpack_from("<BHI", data, 104)
    if not HEADER_BYTES <= header_size <= point_start <= len(data):
        raise MeshFormatError(f"{label}: the header ({header_size} bytes) and the point data "
                              f"(from byte {point_start}) do not fit in the file's "
                              f"{len(data)} bytes")
    if n_vlrs * VLR_HEADER_BYTES > point_start - header_size:
        raise MeshFormatError(f"{label}: the header lists {n_vlrs} variable length records; "
                              f"{point_start - header_size} bytes before the points hold "
                              f"at most {(point_start - header_size) // VLR_HEADER_BYTES}")
    count = legacy_count
    if header_size >= HEADER_BYTES_14 and data[25] >= 4:  # LAS 1.4: extended records
        evlr_start, n_evlrs, count_14 = struct.unpack_from("<QIQ", data, 235)
        count = count_14 or legacy_count
        room = len(data) - evlr_start if evlr_start <= len(data) else 0
        if n_evlrs * EVLR_HEADER_BYTES > room:
            raise MeshFormatError(f"{label}: the header lists {n_evlrs} extended variable "
                                  f"length records from byte {evlr_start}; the file has "
                                  f"{len(data)} bytes")
    if format_id & COMPRESSED_BIT:
        _check_chunk_table(data, label, header_size, n_vlrs, point_start, count)
    elif point_start + count * record_size > len(data):
        raise MeshFormatError(f"{label}: file ends early: the header declares {count} "
                              f"points of {record_size} bytes from byte {point_start}, the "
                              f"file has {len(data)} bytes")


def _chunk_size(data: bytes, header_size: int, n_vlrs: int) -> int | None:
    """The points per chunk the LAZ file's LASzip record gives, or None without one."""
    at = header_size
    for _ in range(n_vlrs):
        user_id = data[at + 2:at + 18].split(b"\0")[0]
        record_id, length = struct.unpack_from("<HH", data, at + 18)
        if (user_id, record_id) == LASZIP_RECORD and length >= 16:
            if at + VLR_HEADER_BYTES + 16 > len(data):
                return None  # cut short: the decoder will say so
            return int(struct.unpack_from("<I", data, at + VLR_HEADER_BYTES + 12)[0])
        at += VLR_HEADER_BYTES + length
        if at > len(data) - VLR_HEADER_BYTES:
            break
    return None


def _check_chunk_table(data: bytes, label: str, header_size: int, n_vlrs: int,
                       point_start: int, count: int) -> None:
    """Refuse a LAZ chunk table that lists more chunks than the points and bytes allow:
    its decoder allocates for the listed count before reading it (a corrupted count of
    billions aborts the process, which no exception handler catches)."""
    if point_start + 8 > len(data):
        raise MeshFormatError(f"{label}: file ends early: no compressed points")
    (table_at,) = struct.unpack_from("<q", data, point_start)
    if table_at == -1:  # written as a stream: the offset is the file's last 8 bytes
        (table_at,) = struct.unpack_from("<q", data, len(data) - 8)
    if not point_start + 8 <= table_at <= len(data) - 8:
        return  # no table to read: the decoder reads the chunks in order
    n_chunks = int(struct.unpack_from("<I", data, table_at + 4)[0])
    chunk_size = _chunk_size(data, header_size, n_vlrs)
    most = count + 1 if chunk_size in (None, 0, VARIABLE_CHUNKS) else count // chunk_size + 2
    most = min(most, table_at - point_start)  # every chunk takes a byte at least
    if n_chunks > most:
        raise MeshFormatError(f"{label}: the chunk table lists {n_chunks} chunks; "
                              f"{count} points in {table_at - point_start} bytes hold at "
                              f"most {most}")


def read_las(data: bytes, label: str = "LAS", limits: ReadLimits | None = None,
             *, keep: int | None = None, seed: int = REDUCE_SEED) -> tuple[FloatArray, int]:
    """A LAS or LAZ file's positions, reduced to at most ``keep`` points.

    Parameters
    ----------
    data : bytes
        The file's content (LAS or LAZ; the header tells which).
    label : str
        The format's name for messages.
    limits : ReadLimits, optional
        ``max_points`` applies to the header's point count, before any point is read.
    keep : int, optional
        Most points returned (None: all); a larger cloud gives the seeded uniform random
        subset of its rows that every other reader keeps.
    seed : int
        Seed of the subset.

    Returns
    -------
    points : (M, 3) float64
        Scaled positions in the file's order, ``M = min(count, keep)``.
    count : int
        Points the file holds.

    Raises
    ------
    MeshFormatError
        Not a readable LAS/LAZ file, no points, a scale or offset that is not finite, or
        fewer points than the header declares.
    TooLargeError
        The header declares more than ``limits.max_points`` points.
    """
    import laspy  # here, not at start-up: 0.1 s for every process that reads no LAS

    limits = limits or UNLIMITED
    if not data.startswith(LAS_MAGIC):
        raise MeshFormatError(f"{label}: not a LAS or LAZ file (it does not start with "
                              "'LASF')")
    try:
        check_header(data, label)
    except struct.error as exc:  # a count or an offset past the end the checks missed
        raise MeshFormatError(f"{label}: file ends early ({exc})") from None
    try:
        # one thread: the parallel decoder allocates a whole chunk of the size the file
        # claims before reading it (a corrupted size of billions aborts the process)
        reader = laspy.open(io.BytesIO(data), laz_backend=laspy.LazBackend.Lazrs)
    except BaseException as exc:
        if not _unreadable(exc):
            raise
        raise MeshFormatError(f"{label}: not a readable LAS or LAZ file ({exc})") from None
    with reader:
        header = reader.header
        count = int(header.point_count)
        if count == 0:
            raise MeshFormatError(f"{label}: the file contains no points")
        limits.check_points(label, count)
        scales = np.asarray(header.scales, dtype=np.float64)
        offsets = np.asarray(header.offsets, dtype=np.float64)
        if not (np.isfinite(scales).all() and np.isfinite(offsets).all()):
            raise MeshFormatError(f"{label}: the header's scales {scales.tolist()} or "
                                  f"offsets {offsets.tolist()} are not finite")
        rows = reduction_indices(count, keep, seed=seed) if keep is not None else None
        kept = count if rows is None else len(rows)
        points = np.empty((kept, 3), dtype=np.float64)  # (M, 3)
        start = filled = 0
        try:
            for chunk in reader.chunk_iterator(CHUNK_POINTS):
                n = len(chunk)
                if n == 0:
                    break
                if rows is None:
                    local = slice(None)
                    taken = n
                else:
                    first, last = np.searchsorted(rows, [start, start + n])
                    local = rows[first:last] - start  # type: ignore[assignment]
                    taken = int(last - first)
                xyz = np.stack([np.asarray(chunk.X, dtype=np.float64)[local],
                                np.asarray(chunk.Y, dtype=np.float64)[local],
                                np.asarray(chunk.Z, dtype=np.float64)[local]], axis=1)
                points[filled:filled + taken] = xyz * scales + offsets
                filled += taken
                start += n
        except BaseException as exc:
            if not _unreadable(exc):
                raise
            raise MeshFormatError(f"{label}: could not read the points ({exc})") from None
    if start < count:
        raise MeshFormatError(f"{label}: file ends early: the header declares {count} "
                              f"points, the file holds {start}")
    return points, count


__all__ = ["CHUNK_POINTS", "LAS_MAGIC", "LAS_TYPES", "check_header", "read_las"]
