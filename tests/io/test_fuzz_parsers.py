"""Fuzzing every reader and every region form: nothing but the documented errors.

Each reader gets random bytes and mutations (flipped, inserted, deleted bytes,
truncations, numbers swapped for huge, negative or non-numeric tokens) of a valid file
of its format, read with limits; anything but a :class:`MeshFormatError` (or a
successful, finite read) fails. Every region form of
:func:`spacemesh.repair.region.parse_region` gets well-formed and malformed values; anything
but a ``RegionError`` fails, on parsing and on selecting faces of a mesh. The runs are
reproducible and bounded (``derandomize=True``, fixed ``max_examples``): seconds in all.
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from spacemesh.examples import icosphere
from spacemesh.io import export_mesh, load_mesh
from spacemesh.io.errors import MeshFormatError
from spacemesh.io.limits import ReadLimits
from spacemesh.io.points import load_points
from spacemesh.repair.region import RegionError, parse_region, region_faces

FUZZ = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
LIMITS = ReadLimits(max_points=2_000, max_vertices=2_000, max_faces=4_000, max_bytes=1_000_000)
MESH = icosphere(1)  # 42 vertices, 80 triangles


def _cloud_files() -> dict[str, bytes]:
    points = MESH.vertices
    npy, npz = io.BytesIO(), io.BytesIO()
    np.save(npy, points)
    np.savez_compressed(npz, points=points, normals=points)
    text = "".join(f"{x} {y} {z}\n" for x, y, z in points.tolist()).encode()
    return {"xyz": text, "pts": b"42\n" + text, "txt": text.replace(b" ", b","),
            "csv": b"x,y,z\n" + text.replace(b" ", b","), "npy": npy.getvalue(),
            "npz": npz.getvalue()}


def _mesh_files() -> dict[str, bytes]:
    files = {fmt: export_mesh(MESH, fmt) for fmt in ("obj", "off", "stl", "glb", "gltf")}
    files["ply"] = export_mesh(MESH, "ply")
    files["ply-ascii"] = export_mesh(MESH, "ply", encoding="ascii")
    facets = "".join(
        "facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n"
                                                     for x, y, z in MESH.vertices[f].tolist())
        + "endloop\nendfacet\n" for f in MESH.faces)
    files["stl-ascii"] = f"solid s\n{facets}endsolid s\n".encode()
    return files


CLOUD_FILES = _cloud_files()
MESH_FILES = _mesh_files()
#: Odd tokens spliced into text formats.
TOKENS = [b"-1", b"0", b"1e300", b"-9223372036854775809", b"nan", b"inf", b"x", b"", b"3.5",
          b"4294967295", b"\xff\xfe", b"#", b"\\", b"/", b"end_header", b"{", b"]", b"OFF",
          b"element vertex 99999999", b"property list uchar int vertex_indices"]


@st.composite
def mutated(draw, seed: bytes) -> bytes:
    """``seed`` with a few random edits, or random bytes."""
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=600))
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 4))):
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        edit = draw(st.sampled_from(["flip", "insert", "delete", "truncate", "token", "dup"]))
        if edit == "flip":
            data[at] = draw(st.integers(0, 255))
        elif edit == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        elif edit == "delete":
            del data[at : at + draw(st.integers(1, 16))]
        elif edit == "truncate":
            del data[at:]
        elif edit == "token":
            data[at : at + draw(st.integers(0, 6))] = draw(st.sampled_from(TOKENS))
        else:
            data[at:at] = data[at : at + draw(st.integers(1, 64))]
    return bytes(data)


def read_or_refuse(read) -> None:
    """A read either succeeds with finite points or raises a MeshFormatError."""
    try:
        result = read()
    except MeshFormatError as error:
        assert str(error)  # a message for the person who sent the file
        return
    vertices = result[0] if isinstance(result, tuple) else result.vertices
    assert vertices.ndim == 2 and vertices.shape[1] == 3 and len(vertices) >= 1
    assert np.isfinite(vertices).all()
    assert len(vertices) <= LIMITS.max_points


@pytest.mark.parametrize("name", sorted(CLOUD_FILES) + sorted(MESH_FILES))
def test_every_reader_refuses_garbage_with_its_documented_error(name):
    seed = {**CLOUD_FILES, **MESH_FILES}[name]
    file_type = name.split("-")[0]

    @FUZZ
    @given(mutated(seed), st.booleans())
    def fuzz(data: bytes, sniff: bool) -> None:
        chosen = None if sniff else file_type
        read_or_refuse(lambda: load_points(data, file_type=chosen, limits=LIMITS))
        if name in MESH_FILES:
            read_or_refuse(lambda: load_mesh(data, file_type=chosen, limits=LIMITS))

    fuzz()


# ---------------------------------------------------------------------- regions
JSON_LEAF = st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70),
                      st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6),
                      st.sampled_from([1e300, -1e300, 2**63, -(2**63) - 1, 0.5, "0", "1e300"]))
JSON_VALUE = st.recursive(JSON_LEAF, lambda children: st.lists(children, max_size=4)
                          | st.dictionaries(st.text(max_size=6), children, max_size=4),
                          max_leaves=12)
INDEX = st.one_of(st.integers(-100, 200), JSON_LEAF)
POINT = st.one_of(st.lists(st.floats(-3, 3), min_size=3, max_size=3),
                  st.lists(JSON_LEAF, max_size=4), JSON_VALUE)
RADIUS = st.one_of(st.floats(0, 3), JSON_LEAF)
REGIONS = st.one_of(
    st.builds(lambda v: {"faces": v}, st.lists(INDEX, max_size=12) | JSON_VALUE),
    st.builds(lambda v: {"vertices": v}, st.lists(INDEX, max_size=12) | JSON_VALUE),
    st.builds(lambda c, r: {"sphere": {"center": c, "radius": r}}, POINT, RADIUS),
    st.builds(lambda lo, hi: {"box": {"min": lo, "max": hi}}, POINT, POINT),
    st.builds(lambda m: {"auto": m}, st.sampled_from(["holes", "defects", "all"]) | JSON_LEAF),
    st.builds(lambda k, v: {k: v}, st.sampled_from(["sphere", "box"]), JSON_VALUE),
    st.dictionaries(st.sampled_from(["faces", "vertices", "sphere", "box", "auto", "x"]),
                    JSON_VALUE, max_size=3),
    JSON_VALUE,
)


@settings(FUZZ, max_examples=400)
@given(REGIONS)
def test_every_region_form_is_read_or_refused_as_a_region_error(raw):
    try:
        region = parse_region(raw)
    except RegionError as error:
        assert error.kind == "invalid-region" and str(error)
        return
    assert region.kind in ("faces", "vertices", "sphere", "box", "auto")
    if region.is_auto:
        return
    try:
        mask = region_faces(MESH, region)
    except RegionError as error:
        assert error.kind in ("invalid-region", "empty-region", "whole-mesh-region")
        return
    assert mask.shape == (MESH.n_faces,) and 0 < mask.sum() < MESH.n_faces


@settings(FUZZ, max_examples=150)
@given(REGIONS)
def test_the_service_reads_regions_as_problems_only(raw):
    from spacemesh_service.inputs import read_limits, read_region
    from spacemesh_service.problems import Problem
    from spacemesh_service.settings import Settings

    limits = read_limits(Settings())
    try:
        text = json.dumps(raw)
    except ValueError:  # pragma: no cover - every drawn value is JSON
        return
    for form in (text, text.encode(), raw):
        try:
            read_region(form, limits)
        except Problem as problem:
            assert problem.kind.status in (400, 413, 422) and problem.detail
