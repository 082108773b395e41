"""Unit tests of the service's parts that need no server: settings, inputs, problems."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spacemesh_service import problems as P
from spacemesh_service.inputs import (
    check_degenerate,
    parse_options,
    read_json,
    read_mesh_upload,
    read_region,
    read_upload,
    validate_cloud,
)
from spacemesh_service.outputs import OUTPUT_FORMATS, stats_headers, validate_mesh
from spacemesh_service.problems import Problem
from spacemesh_service.settings import Settings
from tests.factories import cube_quads


def kind_of(call) -> str:
    with pytest.raises(Problem) as info:
        call()
    return info.value.kind.slug


def test_settings_flags_env_defaults():
    env = {"SPACEMESH_PORT": "9000", "SPACEMESH_MAX_BATCH_SIZE": "8", "SPACEMESH_GRPC": "false"}
    settings = Settings.from_env(env, port=9100)
    assert settings.port == 9100  # an explicit value wins
    assert settings.max_batch_size == 8 and settings.grpc is False
    assert Settings.from_env({}).grpc_port == 8001
    assert Settings.env_name("max_upload_bytes") == "SPACEMESH_MAX_UPLOAD_BYTES"
    assert Settings.from_env({}).intra_op_threads >= 1  # always explicit
    with pytest.raises(ValueError, match="SPACEMESH_QUEUE_SIZE"):
        Settings.from_env({"SPACEMESH_QUEUE_SIZE": "0"})


def test_problem_types_are_stable_and_unique():
    assert P.QUEUE_FULL.type == "https://spacemesh.dev/problems/queue-full"
    assert len({k.type for k in P.KINDS.values()}) == len(P.KINDS)
    problem = Problem(P.QUEUE_FULL, "busy", retry_after=3)
    assert problem.headers() == {"Retry-After": "3"}
    assert ("problem-type", P.QUEUE_FULL.type) in problem.grpc_metadata()
    assert problem.to_dict("/generate")["status"] == 503


def test_region_problems():
    from spacemesh.repair import RegionError
    from spacemesh.repair.region import ERROR_KINDS

    assert {k.slug for k in P.REGION_KINDS} == set(ERROR_KINDS)
    assert all(k.status == 422 and P.KINDS[k.slug] is k for k in P.REGION_KINDS)
    error = RegionError("defects-outside-region", "open edges",
                        {"defects": [{"kind": "open-boundary", "count": np.int64(4),
                                      "vertices": np.arange(3)}]})
    problem = P.region_problem(error)
    assert problem.kind is P.DEFECTS_OUTSIDE_REGION and problem.detail == "open edges"
    body = problem.to_dict("/repair")
    assert body["defects"] == [{"kind": "open-boundary", "count": 4, "vertices": [0, 1, 2]}]
    metadata = dict(problem.grpc_metadata())
    assert metadata["problem-type"].endswith("/defects-outside-region")
    assert json.loads(metadata["problem-extensions"]) == {"defects": body["defects"]}
    huge = Problem(P.INVALID_REGION, "x", blob="y" * (P.MAX_GRPC_EXTENSIONS + 1))
    assert "problem-extensions" not in dict(huge.grpc_metadata())


def test_repair_inputs():
    from spacemesh.io import export_mesh

    assert read_region('{"faces": [1, 2]}').kind == "faces"
    assert read_region({"sphere": {"center": [0, 0, 0], "radius": 1}}).radius == 1.0
    assert kind_of(lambda: read_region("{nope")) == "malformed-input"
    assert kind_of(lambda: read_region(" ")) == "malformed-input"
    assert kind_of(lambda: read_region("[" * 100_000)) == "malformed-input"
    for bad in ('{"faces": "1"}', '{"sphere": {"radius": 1}}', '{"box": 3}', "7", "null",
                '{"faces": [1e400]}', '{"vertices": [true]}', '{"faces": [NaN]}'):
        assert kind_of(lambda b=bad: read_region(b)) == "invalid-region", bad
    cube = cube_quads()
    mesh, source = read_mesh_upload(export_mesh(cube, "off"), "cube.off")
    assert source == "off" and mesh.n_faces == 6
    assert read_mesh_upload(export_mesh(cube, "ply"), "no-extension")[1] == "ply"  # sniffed
    assert kind_of(lambda: read_mesh_upload(b"  ", "m.obj")) == "malformed-input"
    assert kind_of(lambda: read_mesh_upload(b"v 0 0 0\n", "m.obj")) == "malformed-input"
    assert kind_of(lambda: read_mesh_upload(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n",
                                            "m.off")) == "malformed-input"
    assert kind_of(lambda: read_mesh_upload(bytes(range(256)) * 4, "m.doc")) == (
        "unsupported-format")


def test_options():
    settings = Settings.from_env({}, max_steps=100)
    opts = parse_options({"format": "OBJ", "seed": "7", "steps": 20}, settings,
                         max_model_steps=64)
    assert (opts.format, opts.seed, opts.steps) == ("obj", 7, 20)
    assert parse_options({}, settings, max_model_steps=64).format == "glb"
    assert 0 <= parse_options({}, settings, max_model_steps=64).seed < 2**31
    assert parse_options({}, settings, max_model_steps=64).steps is None
    for bad in ({"format": "stl"}, {"seed": -1}, {"seed": "x"}, {"steps": 0},
                {"steps": 65}, {"steps": 2.5}, {"seed": True}):
        assert kind_of(lambda b=bad: parse_options(b, settings, max_model_steps=64)) == (
            "invalid-parameter")
    assert set(OUTPUT_FORMATS) == {"glb", "gltf", "obj", "ply", "off", "json"}


def test_weld_option():
    settings = Settings.from_env({}, max_steps=100)

    def weld(value):
        return parse_options({"weld": value}, settings, max_model_steps=64).weld

    assert parse_options({}, settings, max_model_steps=64).weld is False
    for value in (True, "true", "True", " 1 ", "yes", "on", 1):
        assert weld(value) is True, value
    for value in (False, None, "", "false", "0", "no", "OFF", 0):
        assert weld(value) is False, value
    for bad in ("maybe", "2", 2, "tru"):
        assert kind_of(lambda b=bad: weld(b)) == "invalid-parameter", bad


def test_uploads_and_json():
    points, normals, source = read_upload(b"0 0 0\n1 0 0\n0 1 0\n", "a.xyz")
    assert source == "xyz" and points.shape == (3, 3) and normals is None
    assert kind_of(lambda: read_upload(b"ply\nformat ascii 1.0\nnonsense", "a.ply")) == (
        "malformed-input")
    assert kind_of(lambda: read_upload(b"\x00\x01binary junk", "a.docx")) == (
        "unsupported-format")
    assert kind_of(lambda: read_upload(b"", "a.xyz")) == "malformed-input"
    assert kind_of(lambda: read_upload(b"0 0 nan\n1 0 0\n0 1 0\n", "a.xyz")) == "non-finite"
    points, normals, options = read_json(b'{"points": [[0, 0, 0], [1, 2, 3]], "seed": 4}')
    assert points.shape == (2, 3) and options == {"seed": 4}
    for body in (b"{", b"[1, 2]", b'{"points": [[0, 0]]}', b'{"points": [["a", 0, 0]]}',
                 b'{"points": [[0, 0, 0], [1, 2]]}', b'{"points": [[null, 0, 0]]}'):
        assert kind_of(lambda b=body: read_json(b)) == "malformed-input", body
    assert kind_of(lambda: read_json(b'{"points": [], "colour": 1}')) == "invalid-parameter"


def test_cloud_validation():
    settings = Settings.from_env({}, min_points=4, max_points=100)
    rng = np.random.default_rng(0)
    good = rng.standard_normal((50, 3))
    assert validate_cloud(good, None, settings, source="json").points.shape == (50, 3)
    assert kind_of(lambda: validate_cloud(good[:3], None, settings, source="x")) == (
        "too-few-points")
    many = rng.standard_normal((101, 3))
    assert kind_of(lambda: validate_cloud(many, None, settings, source="x")) == (
        "too-many-points")
    bad = good.copy()
    bad[3, 1] = np.inf
    assert kind_of(lambda: validate_cloud(bad, None, settings, source="x")) == "non-finite"
    assert kind_of(lambda: validate_cloud(good, good[:5], settings, source="x")) == (
        "invalid-normals")
    assert kind_of(lambda: validate_cloud(good, None, settings, source="x",
                                          needs_normals=True)) == "normals-required"
    t = rng.standard_normal((20, 1))
    line = np.hstack([t, 2 * t, -t]) + 5.0
    plane = np.hstack([rng.standard_normal((20, 2)), np.zeros((20, 1))]) @ np.array(
        [[1, 0, 0.5], [0, 1, 0.25], [0, 0, 1.0]]) + 100.0
    same = np.ones((20, 3))
    for cloud, word in ((same, "identical"), (line, "collinear"), (plane, "coplanar")):
        with pytest.raises(Problem, match=word):
            check_degenerate(cloud)


def test_mesh_validation_and_headers():
    _, stats = validate_mesh(cube_quads())
    assert stats.face_degrees == {4: 6} and stats.closed and stats.oriented and stats.genus == 0
    headers = stats_headers(stats)
    assert headers["X-SpaceMesh-Face-Degrees"] == "4:6"
    assert headers["X-SpaceMesh-Manifold"] == "true"
    from spacemesh.mesh import PolygonMesh

    assert kind_of(lambda: validate_mesh(PolygonMesh.empty())) == "no-surface"
    open_mesh = PolygonMesh.from_faces(np.eye(3), [[0, 1, 2]])
    assert kind_of(lambda: validate_mesh(open_mesh)) == "invalid-output"


def test_every_setting_is_a_flag_with_its_env_var():
    from typer.testing import CliRunner

    from spacemesh.cli import _register, app

    _register()
    result = CliRunner().invoke(app, ["serve", "--help"], terminal_width=200,
                                env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    for name in Settings.model_fields:
        assert f"--{name.replace('_', '-')}" in result.output, name
        assert Settings.env_name(name) in result.output, name
