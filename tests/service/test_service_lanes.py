"""The two lanes: requests routed by their estimated cost, a light lane that a heavy
request never holds up (the lanes alone with a gated fake generator, then a real server
on loopback with the tiny model: a small generate answers 200 while a heavy one runs)."""

from __future__ import annotations

import asyncio
import re
import threading

import httpx
import numpy as np
import pytest
from service_testing import ADMIT_ALL, as_ply, wait_for

from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.budget import Budget
from spacemesh.runtime.cost import Estimate
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.request import GenerateRequest, GenerateResult
from spacemesh_service.lanes import Lanes
from spacemesh_service.metrics import Metrics
from spacemesh_service.settings import Settings

#: The seed of the fake's heavy request: its batch waits for the gate.
HEAVY_SEED = 99
#: A heavy request on the tiny model: seconds of work where the defaults take a fraction
#: of one (estimated far above the light lane of the server below).
HEAVY_OPTIONS = {"start": "points", "samples": 16, "target_vertices": 4000}


def cost(seconds: float, memory_mb: float = 10.0) -> Estimate:
    return Estimate(seconds, memory_mb, (), lambda changes: (seconds, memory_mb))


def request(seed: int) -> GenerateRequest:
    return GenerateRequest(np.zeros((4, 3)), options=GenerateOptions(seed=seed, steps=4,
                                                                     sampler="ddim"))


class HeldGenerator:
    """Answers every request at once, but a batch holding :data:`HEAVY_SEED` first waits
    for :attr:`gate` (set :attr:`entered` when it starts)."""

    def __init__(self) -> None:
        self.gate, self.entered = threading.Event(), threading.Event()

    def generate_batch(self, requests, *, progress=None, stage=None):
        if any(r.options.seed == HEAVY_SEED for r in requests):
            self.entered.set()
            self.gate.wait(30)
        return [GenerateResult(PolygonMesh.empty(), r.options, timings={})
                for r in requests]


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, 60))


# ---------------------------------------------------------------------- the lanes alone
def test_a_held_main_lane_does_not_hold_the_light_one():
    fake, metrics = HeldGenerator(), Metrics()

    async def scenario():
        lanes = Lanes(fake.generate_batch, light=Budget(5.0, 100.0), max_batch_size=4,
                      max_delay_s=0.0, queue_size=2, metrics=metrics)
        lanes.start()
        heavy_lane = lanes.for_cost(cost(50.0))
        heavy = asyncio.ensure_future(heavy_lane.submit(request(HEAVY_SEED)))
        while not fake.entered.is_set():
            await asyncio.sleep(0.01)
        light = await lanes.for_cost(cost(1.0)).submit(request(1))  # while held
        still_running = not heavy.done()
        reason = lanes.overload(0.0)  # the held batch runs past a zero deadline
        fake.gate.set()
        await heavy
        assert await lanes.close(5)
        return heavy_lane.lane, light, still_running, reason

    lane, light, still_running, reason = run(scenario())
    assert lane == "main" and light.result.seed == 1 and still_running
    assert reason is not None and reason.startswith("main lane: the running batch")
    text = metrics.render().decode()
    assert 'spacemesh_lane_requests_total{lane="light"} 1.0' in text
    assert 'spacemesh_lane_requests_total{lane="main"} 1.0' in text


def test_requests_are_routed_by_seconds_and_memory():
    lanes = Lanes(HeldGenerator().generate_batch, light=Budget(5.0, 100.0),
                  max_batch_size=1, max_delay_s=0.0, queue_size=1)
    assert lanes.light is not None
    assert lanes.for_cost(cost(5.0, 100.0)) is lanes.light  # at the limits: light
    assert lanes.for_cost(cost(5.1)) is lanes.main
    assert lanes.for_cost(cost(0.1, 101.0)) is lanes.main
    one = Lanes(HeldGenerator().generate_batch, light=None, max_batch_size=1,
                max_delay_s=0.0, queue_size=1)
    assert one.light is None and one.all == [one.main]
    assert one.for_cost(cost(0.0)) is one.main


def test_each_lane_has_its_own_queue_and_the_total_adds_them():
    fake, metrics = HeldGenerator(), Metrics()

    async def scenario():
        lanes = Lanes(fake.generate_batch, light=Budget(5.0, None), max_batch_size=1,
                      max_delay_s=0.0, queue_size=1, metrics=metrics)
        lanes.start()
        held = asyncio.ensure_future(lanes.main.submit(request(HEAVY_SEED)))
        while not fake.entered.is_set():
            await asyncio.sleep(0.01)
        waiting = asyncio.ensure_future(lanes.main.submit(request(HEAVY_SEED + 1)))
        await asyncio.sleep(0)
        depths = lanes.main.depth, lanes.depth
        text = metrics.render().decode()
        fine = await lanes.for_cost(cost(0.5)).submit(request(2))  # main's queue is full
        fake.gate.set()
        await asyncio.gather(held, waiting)
        await lanes.close(5)
        return depths, text, fine

    depths, text, fine = run(scenario())
    assert depths == (1, 1) and fine.result.seed == 2
    assert 'spacemesh_lane_queue_depth{lane="main"} 1.0' in text
    assert 'spacemesh_lane_running_requests{lane="main"} 1.0' in text
    assert re.search(r"^spacemesh_queue_depth 1\.0$", text, re.M)


def test_the_light_lane_settings_have_flags_and_variables():
    settings = Settings()
    assert settings.light_lane == Budget(0.25 * settings.request_timeout_s, 512.0)
    assert Settings.from_env({}, request_timeout_s=60).light_lane == Budget(15.0, 512.0)
    env = {"SPACEMESH_LIGHT_LANE_S": "3", "SPACEMESH_LIGHT_LANE_MB": "64"}
    assert Settings.from_env(env).light_lane == Budget(3.0, 64.0)
    assert Settings.from_env(env, light_lane_s=0).light_lane is None  # the flag wins
    assert Settings.from_env({}, light_lane_s=0).limits()["light_lane_s"] == 0.0
    with pytest.raises(ValueError, match="SPACEMESH_LIGHT_LANE_S"):
        Settings.from_env({"SPACEMESH_LIGHT_LANE_S": "-1"})


# ---------------------------------------------------------------------- on a server
def lane_metric(url: str, name: str, lane: str) -> float:
    text = httpx.get(url + "/metrics").text
    match = re.search(rf'^{name}{{lane="{lane}"}} (\S+)$', text, re.M)
    return float(match.group(1)) if match else 0.0


@pytest.mark.slow
def test_a_small_generate_succeeds_while_a_heavy_one_runs(start_server, generator, case):
    server = start_server(generator, light_lane_s=5.0, **ADMIT_ALL)
    url, cloud = server.url, as_ply(case.points)
    heavy_query = {**HEAVY_OPTIONS, "seed": case.good_seed, "format": "obj"}
    with httpx.Client(base_url=url, timeout=120) as client, client.stream(
            "POST", "/generate/stream", params=heavy_query,
            files={"file": ("cloud.ply", cloud)}) as heavy:
        assert heavy.status_code == 200
        lines = heavy.iter_lines()  # kept: closing the iterator closes the connection
        while '"stage":"encoder"' not in next(lines).replace(" ", ""):
            pass  # until the heavy request runs
        assert lane_metric(url, "spacemesh_lane_running_requests", "main") == 1
        small = httpx.post(url + "/generate", params={"seed": case.good_seed, "format": "obj"},
                           files={"file": ("cloud.ply", cloud)}, timeout=60)
        assert small.status_code == 200, small.text
        # the heavy request has not finished: it still holds the main lane
        assert lane_metric(url, "spacemesh_lane_running_requests", "main") == 1
        assert lane_metric(url, "spacemesh_lane_requests_total", "light") == 1
        assert lane_metric(url, "spacemesh_lane_requests_total", "main") == 1
        lines.close()
    # the heavy client went away: its work stops
    wait_for(lambda: lane_metric(url, "spacemesh_lane_running_requests", "main") == 0,
             "the heavy request to stop", timeout=60.0)
