"""Unit tests of the service's parts that need no server: settings, inputs, problems."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spacemesh.runtime.cloud import CloudError, check_degenerate
from spacemesh_service import problems as P
from spacemesh_service.inputs import (
    read_json,
    read_mesh_upload,
    read_region,
    read_upload,
    validate_cloud,
)
from spacemesh_service.options import (
    GENERATE_OPTIONS,
    GENERATE_ROUTE_OPTIONS,
    REPAIR_ROUTE_OPTIONS,
    attribute_docs,
    resolve_request,
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
    assert Settings.from_env({}).network_threads >= 1  # always explicit
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


def toy_spec(**changes):
    """A model spec without networks: 64 timesteps, 8 default steps, start=noise."""
    from dataclasses import replace

    from spacemesh.decode import DecodeOptions
    from spacemesh.runtime.schedule import NoiseSchedule
    from spacemesh.runtime.spec import ModelSpec

    spec = ModelSpec(n_points=64, max_vertices=16, normals=False,
                     schedule=NoiseSchedule(np.linspace(1e-4, 0.02, 64)), method="ddim",
                     steps=8, decode=DecodeOptions())
    return replace(spec, **changes)


def resolve(values, table=GENERATE_ROUTE_OPTIONS, spec=None, **settings):
    return resolve_request(values, table, spec or toy_spec(),
                           Settings.from_env({}, **{"max_steps": 100, **settings}))


def test_options():
    opts = resolve({"format": "OBJ", "seed": "7", "steps": 20})
    assert (opts.format, opts.resolved.seed, opts.resolved.steps) == ("obj", 7, 20)
    assert opts.sent.seed == 7 and opts.sent.start is None  # as sent, the policy applied
    assert resolve({}).format == "glb"
    assert 0 <= resolve({}).resolved.seed < 2**31
    assert resolve({}).sent.steps is None and resolve({}).resolved.steps == 8
    assert resolve({"seed": str(2**62 + 1)}).resolved.seed == 2**62 + 1  # exact
    assert resolve({}, default_steps=12).resolved.steps == 12
    assert kind_of(lambda: resolve({"format": "stl"})) == "invalid-option"
    for bad in ({"seed": -1}, {"seed": "x"}, {"steps": 0}, {"steps": 65}, {"steps": 2.5},
                {"seed": True}, {"sampler": "euler"}):
        assert kind_of(lambda b=bad: resolve(b)) == "invalid-option", bad
    assert set(OUTPUT_FORMATS) == {"glb", "gltf", "obj", "ply", "off", "json"}


def test_what_reaches_the_generator_is_typed():
    """``seed=1e3`` once passed the check while the text itself reached the pipeline (a
    TypeError there: a 500); every option is now parsed once, by one rule."""
    opts = resolve({"seed": "7", "samples": "2", "start": "points", "target_vertices": "60",
                    "start_time": "0.5", "raw": "false"})
    for options in (opts.sent, opts.resolved):
        assert (type(options.seed), type(options.samples), type(options.target_vertices),
                type(options.start_time), type(options.raw)) == (int, int, int, float, bool)
    for values, name in (({"seed": "1e3"}, "seed"), ({"seed": "1.0"}, "seed"),
                         ({"seed": 1.0}, "seed"), ({"samples": "2.0"}, "samples"),
                         ({"start": "points", "target_vertices": "500.0"}, "target_vertices"),
                         ({"start": "points", "target_vertices": 500.0}, "target_vertices"),
                         ({"steps": "4.0"}, "steps")):
        with pytest.raises(Problem) as info:
            resolve(values)
        assert info.value.kind is P.INVALID_OPTION and info.value.extra == {"option": name}
        assert "must be an integer" in info.value.detail


def test_names_a_route_does_not_take_are_refused():
    with pytest.raises(Problem) as info:
        resolve({"seed": 1, "colour": "red", "alpha": 2})
    assert info.value.kind is P.INVALID_OPTION and info.value.kind.status == 422
    assert info.value.extra == {"option": "alpha", "unknown": ["alpha", "colour"]}
    assert "'alpha', 'colour'" in info.value.detail and "seed" in info.value.detail
    with pytest.raises(Problem) as info:
        resolve({"tolerance": "0.01"}, REPAIR_ROUTE_OPTIONS)
    assert info.value.extra == {"option": "tolerance", "unknown": ["tolerance"]}


def test_settings_max_steps_is_checked_with_the_options():
    assert resolve({"steps": 30}, max_steps=30).resolved.steps == 30
    with pytest.raises(Problem) as info:
        resolve({"steps": 31}, max_steps=30)
    assert info.value.kind.slug == "invalid-option" and info.value.extra == {"option": "steps"}
    assert "1..30" in info.value.detail


@pytest.mark.parametrize(("values", "option"), [
    ({"start": "bogus"}, "start"),
    ({"start_time": 0.5}, "start_time"),  # start_time with the default start (noise)
    ({"start": "noise", "start_time": "0.5"}, "start_time"),
    ({"start": "points", "start_time": 2}, "start_time"),
    ({"start": "points", "start_time": "abc"}, "start_time"),
    ({"start": "points", "target_vertices": 3}, "target_vertices"),
    ({"start": "points", "target_vertices": "20000"}, "target_vertices"),
    ({"target_vertices": 100}, "target_vertices"),  # needs start=points
    ({"samples": 0}, "samples"),
    ({"samples": "17"}, "samples"),
    ({"raw": "maybe"}, "raw"),
])
def test_generate_option_errors_name_the_option(values, option):
    with pytest.raises(Problem) as info:
        resolve(values)
    assert info.value.kind is P.INVALID_OPTION and info.value.kind.status == 422
    assert info.value.extra == {"option": option}, info.value.detail


def test_new_generate_options_resolve():
    opts = resolve({"start": "points", "start_time": "0.25", "target_vertices": "100",
                    "samples": "4", "raw": "true"})
    r = opts.resolved
    assert (r.start, r.start_time, r.target_vertices, r.samples, r.raw) == (
        "points", 0.25, 100, 4, True)
    assert opts.batch_key == (8, "ddim", "points", 0.25)
    spec = toy_spec(start="points", start_time=0.5)
    assert resolve({}, spec=spec).resolved.start_time == 0.5  # the model's default


def test_repair_takes_no_generate_only_option():
    names = {o.name for o in REPAIR_ROUTE_OPTIONS}
    assert names == {"format", "seed", "steps", "sampler", "weld", "max_growth"}
    with pytest.raises(Problem) as info:
        resolve({"start": "bogus", "samples": 0}, REPAIR_ROUTE_OPTIONS)
    assert info.value.kind is P.INVALID_OPTION
    assert info.value.extra == {"option": "samples", "unknown": ["samples", "start"]}
    assert "samples (an option of /generate only)" in info.value.detail


def test_the_option_table_is_generate_options():
    from spacemesh.runtime.options import OPTION_FIELDS

    assert tuple(o.name for o in GENERATE_OPTIONS) == OPTION_FIELDS
    assert [o.name for o in GENERATE_ROUTE_OPTIONS] == ["format", *OPTION_FIELDS]
    kinds = {o.name: o.kind for o in GENERATE_OPTIONS}
    assert kinds == {"seed": int, "steps": int, "sampler": str, "start": str,
                     "start_time": float, "target_vertices": int, "tolerance": float,
                     "samples": int, "raw": bool, "surface": str, "face_type": str}
    assert all(o.description for o in GENERATE_OPTIONS)
    assert "farthest-point" in {o.name: o.description for o in GENERATE_OPTIONS}["start"]


def test_attribute_docs_reads_a_numpydoc_section():
    class Example:
        """Summary.

        Attributes
        ----------
        a : int
            First line
            second line, see :class:`~pkg.Thing` and ``code``.
        b : str, optional

        Methods
        -------
        c : not an attribute
        """

    assert attribute_docs(Example) == {
        "a": "First line second line, see pkg.Thing and `code`.", "b": ""}


def test_weld_option():
    def weld(value):
        return resolve({"weld": value}, REPAIR_ROUTE_OPTIONS).weld

    assert resolve({}, REPAIR_ROUTE_OPTIONS).weld is False
    for value in (True, "true", "True", " 1 ", "yes", "on", 1):
        assert weld(value) is True, value
    for value in (False, None, "", "false", "0", "no", "OFF", 0):
        assert weld(value) is False, value
    for bad in ("maybe", "2", 2, "tru"):
        assert kind_of(lambda b=bad: weld(b)) == "invalid-option", bad


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
    assert kind_of(lambda: read_json(b'{"points": [], "colour": 1}')) == "invalid-option"


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
        with pytest.raises(CloudError, match=word) as info:
            check_degenerate(cloud)
        assert info.value.kind == "degenerate-geometry"
        assert kind_of(lambda c=cloud: validate_cloud(c, None, settings, source="x")) == (
            "degenerate-geometry")


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


def test_the_fit_report_becomes_headers_json_and_grpc_by_its_field_names():
    from dataclasses import fields as dataclass_fields
    from dataclasses import replace

    from spacemesh.geometry.report import FitReport, fit_report
    from spacemesh_service.grpc_server import stats_to_pb
    from spacemesh_service.outputs import encode_mesh

    mesh = cube_quads()
    plain = fit_report(mesh, mesh.vertices)
    fit = replace(plain, tolerance=0.01, tolerance_met=True, points_pieces=1,
                  points_outliers=0.05, points_noise=0.004, open_surface=False,
                  unsupported_area=0.02).to_dict()
    assert set(fit) - set(plain.to_dict()) == {"tolerance", "tolerance_met", "points_pieces",
                                               "points_outliers", "points_noise",
                                               "open_surface", "unsupported_area"}
    encoded = encode_mesh(mesh, "json", {"seed": 1}, fit)
    assert json.loads(encoded.body)["stats"]["fit"] == fit
    headers = stats_headers(encoded.stats)
    names = [f.name for f in dataclass_fields(FitReport)]
    fit_headers = {k for k in headers if k.startswith("X-SpaceMesh-Fit-")}
    assert len(fit_headers) == len(names)
    assert headers["X-SpaceMesh-Fit-Points-To-Mesh-Mean-Rel"] == str(fit["points_to_mesh_mean_rel"])
    assert headers["X-SpaceMesh-Fit-Self-Intersections"] == str(fit["self_intersections"])
    assert headers["X-SpaceMesh-Fit-Components"] == "1"
    assert headers["X-SpaceMesh-Fit-Tolerance-Met"] == "true"
    assert headers["X-SpaceMesh-Fit-Points-Pieces"] == "1"
    assert headers["X-SpaceMesh-Fit-Points-Outliers"] == "0.05"
    assert headers["X-SpaceMesh-Fit-Points-Noise"] == "0.004"
    assert headers["X-SpaceMesh-Fit-Open-Surface"] == "false"
    assert headers["X-SpaceMesh-Fit-Unsupported-Area"] == "0.02"
    message = stats_to_pb(encoded.stats)
    assert {f.name: getattr(message.fit, f.name) for f in message.fit.DESCRIPTOR.fields} == fit
    without = stats_to_pb(replace(encoded.stats, fit=plain.to_dict())).fit
    assert not without.HasField("tolerance") and not without.HasField("tolerance_met")
    assert not without.HasField("points_pieces")
    assert not without.HasField("points_outliers") and not without.HasField("points_noise")
    assert not stats_to_pb(replace(encoded.stats, fit=None)).HasField("fit")
    nan = {**fit, "points_to_mesh_mean": float("nan")}
    assert json.loads(encode_mesh(mesh, "json", {}, nan).body)["stats"]["fit"][
        "points_to_mesh_mean"] is None


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
