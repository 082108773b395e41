"""LAS and LAZ point clouds (:mod:`spacemesh.io.las`), read through
:func:`spacemesh.io.points.read_points` as every other cloud is."""

from __future__ import annotations

import io
import struct

import laspy
import numpy as np
import pytest

from spacemesh.io import las as las_module
from spacemesh.io.errors import MeshFormatError, TooLargeError
from spacemesh.io.limits import ReadLimits
from spacemesh.io.points import is_binary_cloud, read_points
from spacemesh.io.reduce import reduce_cloud

#: Where a LAS header keeps its x scale (then y, z, and the three offsets), as doubles.
SCALE_OFFSET_BYTES = 131


def las_bytes(points: np.ndarray, *, compressed: bool = False, point_format: int = 3,
              scale: float = 1e-3) -> bytes:
    header = laspy.LasHeader(point_format=point_format, version="1.4")
    header.scales = np.full(3, scale)
    header.offsets = points.min(axis=0)
    data = laspy.LasData(header)
    data.x, data.y, data.z = points.T
    buffer = io.BytesIO()
    data.write(buffer, do_compress=compressed)
    return buffer.getvalue()


@pytest.fixture
def cloud() -> np.ndarray:
    return np.random.default_rng(3).normal(size=(2_000, 3)) * [40.0, 20.0, 5.0]


@pytest.mark.parametrize("compressed", [False, True])
@pytest.mark.parametrize("point_format", [0, 3, 6])
def test_positions_come_back_within_the_scale(cloud, compressed, point_format):
    data = las_bytes(cloud, compressed=compressed, point_format=point_format)
    read = read_points(data, "laz" if compressed else "las")
    assert read.count == len(cloud) and not read.reduced and read.normals is None
    assert read.points.dtype == np.float64 and read.points.flags.c_contiguous
    assert np.abs(read.points - cloud).max() <= 0.5e-3 + 1e-9  # half the scale
    # the content alone tells a LAS or LAZ file: sniffed, and a binary cloud
    assert np.array_equal(read_points(data).points, read.points)
    assert is_binary_cloud(data, "las") and is_binary_cloud(data, "laz")


@pytest.mark.parametrize("compressed", [False, True])
def test_a_reduced_cloud_keeps_the_rows_every_reader_keeps(cloud, compressed, monkeypatch):
    monkeypatch.setattr(las_module, "CHUNK_POINTS", 137)  # many blocks, rows across them
    data = las_bytes(cloud, compressed=compressed)
    whole = read_points(data).points
    read = read_points(data, keep=300, seed=5)
    assert read.count == len(cloud) and read.reduced and read.points.shape == (300, 3)
    expected, _ = reduce_cloud(whole, None, 300, seed=5)  # what NPY and PLY keep
    assert np.array_equal(read.points, expected)


def test_the_point_limit_is_checked_before_any_point_is_read(cloud):
    data = las_bytes(cloud, compressed=True)
    with pytest.raises(TooLargeError) as info:  # the header alone: the points are cut off
        read_points(data[: len(data) // 3], "laz", limits=ReadLimits(max_points=len(cloud) - 1))
    assert info.value.what == "points" and info.value.count == len(cloud)
    assert len(read_points(data, limits=ReadLimits(max_points=len(cloud))).points) == len(cloud)


@pytest.mark.parametrize("compressed", [False, True])
def test_a_file_that_ends_early_is_a_format_error(cloud, compressed):
    data = las_bytes(cloud, compressed=compressed)
    with pytest.raises(MeshFormatError, match=r"LA[SZ]: "):
        read_points(data[: len(data) * 2 // 3], "laz" if compressed else "las")


def test_non_finite_scales_and_other_files_are_format_errors(cloud):
    data = bytearray(las_bytes(cloud))
    struct.pack_into("<d", data, SCALE_OFFSET_BYTES, float("nan"))
    with pytest.raises(MeshFormatError, match="not finite"):
        read_points(bytes(data), "las")
    with pytest.raises(MeshFormatError, match="not a LAS or LAZ file"):
        read_points(b"PLYF" + bytes(300), "las")
    with pytest.raises(MeshFormatError, match="LAS: "):
        read_points(b"LASF" + bytes(20), "las")


@pytest.mark.parametrize("field, offset, fmt", [("variable length records", 100, "<I"),
                                                ("extended variable length records", 243, "<I"),
                                                ("points of", 247, "<Q")])
def test_counts_the_file_cannot_hold_are_refused_from_the_header(cloud, field, offset, fmt):
    # laspy itself would read four billion empty records, one at a time
    data = bytearray(las_bytes(cloud, point_format=6))
    struct.pack_into(fmt, data, offset, 2**32 - 1)
    with pytest.raises(MeshFormatError, match=field):
        read_points(bytes(data), "las")


def test_a_chunk_table_of_billions_of_chunks_is_refused_before_it_is_read(cloud):
    # the LAZ decoder allocates for the listed count first, and a failed allocation
    # aborts the process: no exception would reach the caller
    data = bytearray(las_bytes(cloud, compressed=True))
    (point_start,) = struct.unpack_from("<I", data, 96)
    (table_at,) = struct.unpack_from("<q", data, point_start)
    struct.pack_into("<I", data, table_at + 4, 3_422_552_065)
    with pytest.raises(MeshFormatError, match="chunk table lists 3422552065 chunks"):
        read_points(bytes(data), "laz")


def test_a_panic_of_the_laz_decoder_is_a_format_error(cloud):
    # the first item of the LASzip record says 7 bytes where point format 1 has 20: the
    # Rust decoder panics, and pyo3's PanicException is not an Exception
    data = bytearray(las_bytes(cloud, compressed=True, point_format=1))
    header_size, _, n_vlrs = struct.unpack_from("<HII", data, 94)
    at = header_size
    for _ in range(n_vlrs):
        record_id, length = struct.unpack_from("<HH", data, at + 18)
        if data[at + 2:at + 18].rstrip(b"\0") == b"laszip encoded" and record_id == 22204:
            break
        at += 54 + length
    first_item_size = at + 54 + 36
    assert struct.unpack_from("<H", data, first_item_size)[0] == 20
    struct.pack_into("<H", data, first_item_size, 7)
    with pytest.raises(MeshFormatError, match="LAZ: could not read the points"):
        read_points(bytes(data), "laz")


def test_a_laz_file_cut_anywhere_in_its_records_is_a_format_error(cloud):
    data = las_bytes(cloud, compressed=True)
    header_size, point_start = struct.unpack_from("<HI", data, 94)
    for cut in range(header_size, point_start + 16, 7):  # every cut through the records
        with pytest.raises(MeshFormatError):
            read_points(data[:cut], "laz")
