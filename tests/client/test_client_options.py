"""The SDK's and ``spacemesh-client``'s generate options and fit report, on a real server.

The SDK mirrors ``spacemesh.runtime.options.OPTION_FIELDS`` (it may not import it); the
first tests keep the names in sync, the others send every new option over both transports.
"""

from __future__ import annotations

import asyncio
import inspect
import json
import subprocess
import sys

import pytest
from service_testing import BAD_OPTIONS, as_ply

from spacemesh.geometry.report import FitReport
from spacemesh.runtime.options import OPTION_FIELDS, GenerateOptions
from spacemesh_client import AsyncClient, Client, RetryPolicy
from spacemesh_client import errors as E
from spacemesh_client.cli import build_parser
from spacemesh_client.options import GENERATE_OPTIONS, OPTION_NAMES, REPAIR_OPTION_NAMES

#: Fit report fields that only a tolerance request has.
TOLERANCE_FIELDS = {"tolerance", "tolerance_met"}
#: Keywords of ``generate`` that are not generate options.
NOT_OPTIONS = {"points", "self", "normals", "format", "filename", "progress", "stage"}
CLI = [sys.executable, "-c", "from spacemesh_client.cli import main; main()"]


# ---------------------------------------------------------------------- names in sync
def test_the_sdk_mirrors_the_option_names():
    assert OPTION_NAMES == OPTION_FIELDS
    for method in (Client.generate, AsyncClient.generate):
        names = tuple(p for p in inspect.signature(method).parameters if p not in NOT_OPTIONS)
        assert names == OPTION_FIELDS, method.__qualname__
    for method in (Client.repair, AsyncClient.repair):
        assert set(REPAIR_OPTION_NAMES) <= set(inspect.signature(method).parameters)
    kinds = {o.name: o.kind for o in GENERATE_OPTIONS}
    hints = GenerateOptions.__annotations__
    for name, kind in kinds.items():
        assert kind.__name__ in str(hints[name]), name


#: Flag texts both command lines and the service must read alike.
FLAG_TEXTS = ["7", " +7 ", "-3", "0", "1e3", "1.0", "2.0", "500.0", "0x10", "1_000",
              "\u0661\u0662", "seven", "0.5", ".5", "5.", "5e-3", "-1E2", "nan", "inf",
              "1_0", "half", "ddim", " points "]


@pytest.mark.parametrize("text", FLAG_TEXTS, ids=repr)
def test_the_sdk_parses_flags_by_the_services_rule(text):
    """``spacemesh-client`` (which may not import the model) reads a flag's text as
    ``spacemesh.runtime.options.parse_value`` does: the same values, the same refusals."""
    from spacemesh.runtime.options import OptionError, parse_value

    for option in GENERATE_OPTIONS:
        if option.kind is bool:
            continue  # a flag without a value
        try:
            expected = parse_value(option.name, option.kind, text)
        except OptionError as error:
            with pytest.raises(ValueError) as info:
                option.parse(text)
            assert str(info.value).split(", not ")[0] == str(error).split(", not ")[0]
        else:
            parsed = option.parse(text)
            assert parsed == expected and type(parsed) is type(expected), option.name


def test_a_flag_of_the_wrong_type_is_one_line(capsys):
    for flags in (["--seed", "1e3"], ["--samples", "2.0"], ["--target-vertices", "500.0"],
                  ["--tolerance", "nan"]):
        with pytest.raises(SystemExit) as info:
            build_parser().parse_args(["generate", "c.ply", "-o", "m.obj", *flags])
        assert info.value.code == 2
        lines = capsys.readouterr().err.strip().splitlines()
        name = flags[0][2:].replace("-", "_")
        assert len(lines) == 1 and f"argument {flags[0]}: {name} must be" in lines[0], lines


def test_both_command_lines_have_a_flag_per_option():
    import typer

    from spacemesh.cli import _register, app

    _register()

    parser = build_parser()
    generate_parser = parser._subparsers._group_actions[0].choices["generate"]
    flags = {a.dest: a.option_strings for a in generate_parser._actions}
    for name in OPTION_FIELDS:
        assert flags[name] == ["--" + name.replace("_", "-")], name
    command = typer.main.get_command(app).commands["generate"]
    model_flags = {p.name: p.opts for p in command.params}
    for name in OPTION_FIELDS:
        assert model_flags[name] == ["--" + name.replace("_", "-")], name


# ---------------------------------------------------------------------- SDK
def test_sdk_sends_every_option_and_reads_the_report(client, case):
    cloud = case.points[::2]
    mesh = client.generate(cloud, seed=3, steps=4, sampler="ddim", start="points",
                           start_time=0.0, target_vertices=60, samples=2, raw=False,
                           surface="closed", face_type="polygons", format="obj")
    assert mesh.options == {"seed": mesh.seed, "steps": 4, "sampler": "ddim",
                            "start": "points", "start_time": 0.0, "target_vertices": 60,
                            "samples": 2, "raw": False, "surface": "closed",
                            "face_type": "polygons"}
    assert mesh.stats.fit["face_planarity"] >= 0.0  # the tiny model's own polygons as made
    assert mesh.stats.fit["open_surface"] is False and mesh.stats.closed
    assert mesh.seed in (3, 4) and [s for s, _ in mesh.sample_scores] == [3, 4]
    assert set(mesh.stats.fit) == set(FitReport.__dataclass_fields__) - TOLERANCE_FIELDS
    assert mesh.stats.fit["n_points"] == len(cloud)
    assert mesh.stats.to_dict()["fit"] == mesh.stats.fit
    raw = client.generate(cloud, seed=mesh.seed, start="points", raw=True, format="obj")
    assert raw.options["raw"] is True and raw.options["samples"] == 1
    assert "target_vertices" not in raw.options


def test_a_tolerance_request_reports_the_tolerance_over_both_transports(rest_url, grpc_url,
                                                                       case):
    meshes = []
    for url in (rest_url, grpc_url):
        with Client(url, timeout=60, retry=RetryPolicy.never()) as c:
            meshes.append(c.generate(case.points, seed=case.good_seed, start="points",
                                     tolerance=0.05, format="obj"))
    rest, grpc_mesh = meshes
    assert rest.stats.fit == grpc_mesh.stats.fit and rest.data == grpc_mesh.data
    assert set(rest.stats.fit) == set(FitReport.__dataclass_fields__)
    fit = rest.stats.fit
    assert fit["tolerance"] == 0.05 and isinstance(fit["tolerance_met"], bool)
    assert fit["tolerance_met"] == (fit["points_to_mesh_mean_rel"] <= 0.05)
    assert rest.options["tolerance"] == grpc_mesh.options["tolerance"] == 0.05
    assert "target_vertices" not in rest.options


def test_the_fit_report_is_the_same_over_both_transports(rest_url, grpc_url, case):
    meshes = []
    for url in (rest_url, grpc_url):
        with Client(url, timeout=60, retry=RetryPolicy.never()) as c:
            meshes.append(c.generate(case.points, seed=case.good_seed, format="obj"))
    rest, grpc_mesh = meshes
    assert rest.stats.fit == grpc_mesh.stats.fit and rest.stats.fit is not None
    assert rest.options == grpc_mesh.options and rest.sample_scores == grpc_mesh.sample_scores
    assert rest.data == grpc_mesh.data


@pytest.mark.parametrize(("options", "name"), BAD_OPTIONS)
def test_bad_options_raise_invalid_option(client, case, options, name):
    with pytest.raises(E.InvalidOption) as info:
        client.generate(case.points, **options)
    assert info.value.status == 422 and info.value.extra["option"] == name
    assert isinstance(info.value, E.InvalidRequest)


def test_the_async_client_takes_the_options(url, case):
    async def scenario():
        async with AsyncClient(url, timeout=60, retry=RetryPolicy.never()) as c:
            return await c.generate(case.points[::2], seed=1, start="points", samples=2)

    mesh = asyncio.run(scenario())
    assert mesh.options["start"] == "points" and len(mesh.sample_scores) == 2
    assert mesh.stats.fit is not None


# ---------------------------------------------------------------------- CLI
def test_the_cli_sends_the_options_and_prints_the_fit(url, case, tmp_path):
    cloud = tmp_path / "cloud.ply"
    cloud.write_bytes(as_ply(case.points[::2]))
    out = tmp_path / "mesh.obj"
    args = ["generate", str(cloud), "-o", str(out), "--url", url, "--seed", "2", "--start",
            "points", "--samples", "2", "--target-vertices", "60", "--raw"]
    done = subprocess.run([*CLI, *args, "--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["options"]["start"] == "points" and summary["options"]["raw"] is True
    assert summary["options"]["target_vertices"] == 60 and summary["options"]["samples"] == 2
    assert [s for s, _ in summary["sample_scores"]] == [2, 3]
    assert summary["options"]["surface"] == "closed"  # raw: the closed decode, no decision
    assert set(summary["fit"]) == (set(FitReport.__dataclass_fields__) - TOLERANCE_FIELDS
                                   - {"open_surface", "unsupported_area"})
    done = subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "; fit: points->mesh " in done.stdout and "best of 2 seeds" in done.stdout
    pieces, genus = summary["fit"]["pieces"], summary["fit"]["genus"]
    points_pieces = summary["fit"]["points_pieces"]
    assert (f"; {pieces} piece{'' if pieces == 1 else 's'} (the points: {points_pieces}), "
            f"genus {genus}") in done.stdout
    noise = summary["fit"]["points_noise"]
    assert f"; the points: noise {100 * noise:.2g}% of the diagonal" in done.stdout
