"""Big clouds: the seeded reduction and the binary/text limits of the readers."""

from __future__ import annotations

import io

import numpy as np
import pytest

from spacemesh.io.errors import NonFiniteError, TooLargeError
from spacemesh.io.limits import ReadLimits
from spacemesh.io.points import load_points, read_points
from spacemesh.io.reduce import reduce_cloud, reduction_indices
from spacemesh.io.surface import load_cloud_input


def _cloud(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    points = rng.standard_normal((count, 3)).astype(np.float32).astype(np.float64)
    normals = points / np.linalg.norm(points, axis=1, keepdims=True)
    return points, normals


def _ply(points: np.ndarray, normals: np.ndarray | None = None, binary: bool = True) -> bytes:
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else [])
    header = (f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\n"
              f"element vertex {len(points)}\n"
              + "".join(f"property float {n}\n" for n in names) + "end_header\n")
    table = points if normals is None else np.hstack([points, normals])
    if binary:
        return header.encode() + table.astype("<f4").tobytes()
    return header.encode() + "".join(" ".join(map(repr, row)) + "\n"
                                     for row in table.astype(np.float32).tolist()).encode()


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def test_reduction_is_deterministic_sorted_distinct_and_bounded():
    first = reduction_indices(100_000, 1_000)
    assert first is not None and len(first) == 1_000
    assert np.array_equal(first, reduction_indices(100_000, 1_000))
    assert np.all(np.diff(first) > 0) and first[0] >= 0 and first[-1] < 100_000
    other = reduction_indices(100_000, 1_000, seed=1)
    assert other is not None and not np.array_equal(first, other)
    assert reduction_indices(1_000, 1_000) is None
    with pytest.raises(ValueError, match="keep"):
        reduction_indices(10, 0)


def test_reduced_rows_keep_their_normals():
    points, normals = _cloud(5_000)
    kept, kept_normals = reduce_cloud(points, normals, 700)
    assert kept.shape == (700, 3) and kept_normals is not None and kept_normals.shape == (700, 3)
    rows = reduction_indices(5_000, 700)
    assert np.array_equal(kept, points[rows]) and np.array_equal(kept_normals, normals[rows])
    whole, whole_normals = reduce_cloud(points, normals, None)
    assert np.array_equal(whole, points) and np.array_equal(whole_normals, normals)
    with pytest.raises(ValueError, match="normals"):
        reduce_cloud(points, normals[:10], 700)


@pytest.mark.parametrize("fmt", ["ply", "npy", "npz"])
def test_binary_clouds_are_read_reduced_with_aligned_normals(fmt):
    points, normals = _cloud(30_000, seed=2)
    table = np.hstack([points, normals]).astype(np.float32)
    if fmt == "ply":
        data = _ply(points, normals)
    elif fmt == "npy":
        data = _npy(table)
    else:
        buffer = io.BytesIO()
        np.savez_compressed(buffer, points=table[:, :3], normals=table[:, 3:])
        data = buffer.getvalue()
    read = read_points(data, file_type=fmt, keep=2_000)
    assert read.count == 30_000 and read.reduced and read.points.shape == (2_000, 3)
    rows = reduction_indices(30_000, 2_000)
    assert np.array_equal(read.points, points[rows])
    assert read.normals is not None and np.array_equal(read.normals,
                                                       table[rows, 3:].astype(np.float64))
    again = read_points(data, file_type=fmt, keep=2_000)
    assert np.array_equal(again.points, read.points)
    whole = load_points(data, file_type=fmt)[0]
    assert np.array_equal(whole, points)


def test_a_non_finite_row_is_refused_even_when_it_would_not_be_kept():
    points, _ = _cloud(10_000, seed=3)
    rows = reduction_indices(10_000, 100)
    assert rows is not None
    dropped = int(np.setdiff1d(np.arange(10_000), rows)[0])
    points[dropped, 1] = np.nan
    with pytest.raises(NonFiniteError, match=f"point {dropped} "):
        read_points(_ply(points), file_type="ply", keep=100)


def test_text_clouds_have_their_own_lower_limit():
    limits = ReadLimits(max_points=50_000, max_text_points=1_000)
    points, _ = _cloud(2_000, seed=4)
    assert read_points(_ply(points), file_type="ply", limits=limits).count == 2_000
    assert read_points(_npy(points), file_type="npy", limits=limits).count == 2_000
    for data, fmt in [(_ply(points, binary=False), "ply"),
                      ("\n".join(" ".join(map(repr, p)) for p in points.tolist()).encode(),
                       "xyz")]:
        with pytest.raises(TooLargeError) as caught:
            read_points(data, file_type=fmt, limits=limits)
        assert caught.value.limit == 1_000
    with pytest.raises(TooLargeError) as caught:
        read_points(_npy(_cloud(60_000)[0]), file_type="npy", limits=limits)
    assert caught.value.limit == 50_000


def test_a_faceless_ply_is_a_reduced_cloud_input():
    points, normals = _cloud(9_000, seed=5)
    cloud = load_cloud_input(_ply(points, normals), file_type="ply", keep=500)
    assert cloud.kind == "points" and cloud.count == 9_000 and cloud.points_read == 9_000
    assert len(cloud.points) == 500 and cloud.normals is not None
    small = load_cloud_input(_ply(points[:400]), file_type="ply", keep=500)
    assert small.count is None and small.points_read == 400
