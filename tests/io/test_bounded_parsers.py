"""Every reader refuses what is over its limits before it allocates for it.

Each bomb of :mod:`tests.io.bombs` is about a kilobyte that declares a billion points,
vertices or triangles; read with limits it must raise ``TooLargeError`` while
``tracemalloc`` sees a peak of a few megabytes at most. Text formats must stop reading at
the limit, and files at the limit must still be read.
"""

from __future__ import annotations

import io
import tracemalloc

import numpy as np
import pytest

from spacemesh.io import load_mesh
from spacemesh.io.errors import MeshFormatError, TooLargeError
from spacemesh.io.limits import ReadLimits, iter_lines, load_json
from spacemesh.io.points import load_points
from tests.io.bombs import BOMBS, inflating_npz, json_points, obj_lines, ply_bomb, xyz_lines

LIMITS = ReadLimits(max_points=5_000, max_vertices=10_000, max_faces=20_000,
                    max_bytes=2_000_000)
#: The most a refused bomb may allocate while it is read.
SMALL = 4 * 2**20
MESH_TYPES = ("ply", "off", "stl", "glb", "gltf")


def peak_of(read) -> tuple[BaseException | None, int]:
    """The exception ``read()`` raised (or None) and the peak bytes it allocated."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    error = None
    try:
        read()
    except MeshFormatError as exc:
        error = exc
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    return error, peak


@pytest.mark.parametrize("name", sorted(BOMBS))
def test_every_bomb_is_refused_before_allocating(name):
    file_type, data = BOMBS[name]
    assert len(data) < 4096
    readers = [lambda: load_points(data, file_type=file_type, limits=LIMITS)]
    if file_type in MESH_TYPES:
        readers.append(lambda: load_mesh(data, file_type=file_type, limits=LIMITS))
    for read in readers:
        error, peak = peak_of(read)
        assert isinstance(error, TooLargeError), (name, error)
        assert error.count > error.limit and error.what in ("points", "vertices", "faces",
                                                            "bytes")
        assert peak < SMALL, f"{name}: {peak / 2**20:.1f} MB allocated"


@pytest.mark.parametrize("name", sorted(set(BOMBS) - {"glb-no-view"}))
def test_bombs_are_refused_for_the_bytes_they_lack_even_without_limits(name):
    """A declaration that the bytes present cannot hold is malformed, limits or not."""
    file_type, data = BOMBS[name]
    error, peak = peak_of(lambda: load_points(data, file_type=file_type))
    assert isinstance(error, MeshFormatError) and not isinstance(error, TooLargeError)
    assert "ends early" in str(error) or "expected" in str(error) or "holds" in str(error)
    assert peak < SMALL, f"{name}: {peak / 2**20:.1f} MB allocated"


def test_an_inflating_npz_is_refused_by_its_declared_size():
    data = inflating_npz(2_000_000)  # 48 MB inflated, ~50 KB compressed
    assert len(data) < 200_000
    error, peak = peak_of(lambda: load_points(data, file_type="npz", limits=LIMITS))
    assert isinstance(error, TooLargeError) and error.what == "bytes"
    assert peak < SMALL
    # within the byte limit the member's header is what refuses it
    error, peak = peak_of(lambda: load_points(
        data, file_type="npz", limits=ReadLimits(max_points=5_000, max_bytes=10**9)))
    assert isinstance(error, TooLargeError) and error.what == "points"
    assert error.count == 2_000_000 and peak < SMALL


@pytest.mark.parametrize(("file_type", "make"), [("xyz", xyz_lines), ("txt", xyz_lines),
                                                 ("pts", xyz_lines), ("obj", obj_lines)])
def test_text_rows_stop_at_the_limit(file_type, make):
    data = make(50_000)  # ten times the limit
    error, peak = peak_of(lambda: load_points(data, file_type=file_type, limits=LIMITS))
    assert isinstance(error, TooLargeError) and error.limit == LIMITS.max_points
    assert error.what in ("points", "vertices")
    # the decoded text, and the rows up to the limit: not the 50 000 rows
    assert peak < len(data) + SMALL, f"{peak / 2**20:.1f} MB for {len(data) / 2**20:.1f} MB"
    if file_type == "xyz":  # what the limit saves
        unlimited_error, unlimited_peak = peak_of(lambda: load_points(data, file_type="xyz"))
        assert unlimited_error is None and unlimited_peak > 4 * peak


def test_json_values_are_counted_before_parsing():
    data = json_points(100_000)
    error, peak = peak_of(lambda: load_json(data, "JSON", LIMITS))
    assert isinstance(error, TooLargeError) and error.what == "values"
    assert peak < SMALL
    assert load_json(json_points(5_000), "JSON", LIMITS)["points"][0] == [0.5, 1.5, 2.5]
    with pytest.raises(TooLargeError, match="bytes"):
        load_json(b" " * (LIMITS.max_bytes + 1), "JSON", LIMITS)
    with pytest.raises(MeshFormatError, match="nested too deeply"):
        load_json(b"[" * 100_000 + b"]" * 100_000, "JSON")


def test_ascii_ply_is_split_only_as_far_as_it_is_read():
    """Trailing data after the declared elements is never tokenised."""
    rows = b"0.5 1.5 2.5\n" * 5_000
    data = ply_bomb(5_000, "ascii").split(b"element face")[0] + b"end_header\n" + rows
    data += b"12.25 " * 1_000_000  # 6 MB of tokens nobody asked for
    error, peak = peak_of(lambda: load_points(data, file_type="ply", limits=LIMITS))
    assert error is None
    assert peak < len(data) + SMALL


def test_files_at_the_limits_are_read():
    points = np.arange(LIMITS.max_points * 3, dtype=np.float64).reshape(-1, 3)
    npz = io.BytesIO()
    np.savez_compressed(npz, points=points)
    read, _ = load_points(npz.getvalue(), file_type="npz", limits=LIMITS)
    assert np.array_equal(read, points)
    npy = io.BytesIO()
    np.save(npy, points)
    assert np.array_equal(load_points(npy.getvalue(), file_type="npy", limits=LIMITS)[0], points)
    text = b"".join(f"{x} {y} {z}\n".encode() for x, y, z in points.tolist())
    assert len(load_points(text, file_type="xyz", limits=LIMITS)[0]) == LIMITS.max_points
    with pytest.raises(TooLargeError):
        load_points(text + b"1 2 3\n", file_type="xyz", limits=LIMITS)

    from spacemesh.examples import icosphere
    from spacemesh.io import export_mesh

    mesh = icosphere(3)  # 642 vertices, 1280 triangles
    tight = ReadLimits(max_vertices=mesh.n_vertices, max_faces=mesh.n_faces)
    over = ReadLimits(max_vertices=mesh.n_vertices, max_faces=mesh.n_faces - 1)
    for fmt in ("ply", "obj", "off", "stl", "glb", "gltf"):
        data = export_mesh(mesh, fmt)
        assert load_mesh(data, file_type=fmt, limits=tight).n_faces == mesh.n_faces, fmt
        with pytest.raises(TooLargeError, match="faces"):
            load_mesh(data, file_type=fmt, limits=over)


def test_iter_lines_is_splitlines():
    for text in ("a\nb\r\nc", "a\rb\rc\n", "x\x0by\n\nz", "", "\n", "one", "a\u2028b\r\n\r\n"):
        assert list(iter_lines(text)) == text.splitlines(), repr(text)


def test_the_cli_prints_a_too_large_file_as_one_line_and_exits_2(tmp_path):
    """An archive of more members than any reader reads: TooLargeError, limits or not."""
    import zipfile

    from typer.testing import CliRunner

    from spacemesh.cli import _register, app

    _register()
    source = tmp_path / "many.npz"
    with zipfile.ZipFile(source, "w") as archive:
        for i in range(100):
            archive.writestr(f"a{i}.npy", b"")
    result = CliRunner().invoke(app, ["generate", str(source), "-o", str(tmp_path / "m.obj"),
                                      "--no-progress"])
    assert result.exit_code == 2, result.output
    message = result.output.strip()
    assert "\n" not in message and "100 members" in message and "Traceback" not in message
