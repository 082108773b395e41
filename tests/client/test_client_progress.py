"""Progress of ``generate`` over both transports: the SDK's ``stage=`` callback and the
CLI's progress line on stderr, against a real server."""

from __future__ import annotations

import asyncio
import io
import json
import subprocess
import sys

import pytest
from service_testing import as_ply

from spacemesh_client import AsyncClient, Client, RetryPolicy
from spacemesh_client.progress import ProgressBar

pytestmark = pytest.mark.slow

CLI = [sys.executable, "-c", "from spacemesh_client.cli import main; main()"]
#: Stages every generate request reports (tests/service/test_service_stream.py).
STAGES = ("queued", "encoder", "sampler", "connectivity", "decode", "geometry", "report",
          "encode_output")


def test_stage_callback_gets_the_same_stages_over_both_transports(rest_url, grpc_url, case):
    seen: dict[str, list[tuple[str, int, int]]] = {}
    steps: dict[str, list[tuple[int, int]]] = {}
    data = {}
    for name, url in (("rest", rest_url), ("grpc", grpc_url)):
        seen[name], steps[name] = [], []
        with Client(url, retry=RetryPolicy.never()) as client:
            data[name] = client.generate(
                case.points, seed=case.good_seed, steps=3, start="noise", format="ply",
                progress=lambda done, total, s=steps[name]: s.append((done, total)),
                stage=lambda *event, s=seen[name]: s.append(event)).data
    assert seen["rest"][0][0] == "queued"
    assert {e[0] for e in seen["rest"]} == set(STAGES), seen["rest"]
    assert seen["grpc"] == seen["rest"]
    assert steps["grpc"] == steps["rest"] == [(1, 3), (2, 3), (3, 3)]  # unchanged progress=
    assert data["grpc"] == data["rest"]


def test_progress_bar_rewrites_one_line():
    out = io.StringIO()
    bar = ProgressBar(out, width=4)
    bar.stage("sampler", 2, 4)
    bar.stage("geometry", 1, 1)
    bar.close()
    assert out.getvalue() == ("\rsampler       [##..] 2/4"
                              "\rgeometry      [####] 1/1\n")


@pytest.mark.parametrize("transport", ["rest", "grpc"])
def test_cli_shows_the_stages_on_stderr_only(transport, rest_url, grpc_url, case, tmp_path):
    url = rest_url if transport == "rest" else grpc_url
    cloud = tmp_path / "cloud.ply"
    cloud.write_bytes(as_ply(case.points))
    runs = {}
    for flag in ("--progress", "--no-progress"):
        out = tmp_path / f"mesh{flag}.ply"
        done = subprocess.run([*CLI, "generate", str(cloud), "-o", str(out), "--url", url,
                               "--seed", str(case.good_seed), "--steps", "3", "--json",
                               flag], capture_output=True, timeout=120)
        assert done.returncode == 0, done.stderr
        runs[flag] = (done, out.read_bytes())
    # bytes, decoded without universal newlines (which would turn "\r" into "\n")
    shown, hidden = (subprocess.CompletedProcess(r.args, r.returncode, r.stdout.decode(),
                                                 r.stderr.decode())
                     for r, _ in (runs["--progress"], runs["--no-progress"]))
    for stage in ("queued", "sampler", "connectivity", "geometry", "encode_output"):
        assert stage in shown.stderr, shown.stderr
    assert "\r" in shown.stderr and shown.stderr.endswith("\n")
    assert hidden.stderr == ""  # off, and off by default when stderr is not a terminal
    assert "\r" not in shown.stdout
    summaries = [{k: v for k, v in json.loads(r.stdout).items() if k not in ("output", "seconds")}
                 for r in (shown, hidden)]  # the JSON summary alone, nothing mixed in
    assert summaries[0] == summaries[1]
    assert runs["--progress"][1] == runs["--no-progress"][1]


def test_async_client_reports_stages(url, case):
    seen: list[tuple[str, int, int]] = []

    async def run() -> bytes:
        async with AsyncClient(url, retry=RetryPolicy.never()) as client:
            mesh = await client.generate(case.points, seed=case.good_seed, steps=3, start="noise",
                                         stage=lambda *event: seen.append(event))
            return mesh.data

    assert asyncio.run(run())
    assert [e for e in seen if e[0] == "sampler" and e[1] >= 1] == [("sampler", 1, 3),
                                                                     ("sampler", 2, 3),
                                                                     ("sampler", 3, 3)]
    assert {"queued", "connectivity", "geometry", "encode_output"} <= {e[0] for e in seen}
