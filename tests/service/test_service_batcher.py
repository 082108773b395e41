"""The dynamic batcher alone, with a fake generator (no model, no server)."""

from __future__ import annotations

import asyncio
import threading

import numpy as np
import pytest

from spacemesh.mesh import PolygonMesh
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.request import GenerateRequest, GenerateResult
from spacemesh_service.batcher import Batcher, QueueFull, ShuttingDown


def request(seed: int, steps: int = 4) -> GenerateRequest:
    return GenerateRequest(np.zeros((4, 3)), options=GenerateOptions(seed=seed, steps=steps,
                                                                     sampler="ddim"))


class FakeGenerator:
    """Answers every request; fails the whole batch when it holds seed 13."""

    def __init__(self, gate: threading.Event | None = None) -> None:
        self.batches: list[list[int]] = []
        self.gate = gate

    def generate_batch(self, requests, *, progress=None, stage=None):
        if self.gate is not None:
            self.gate.wait(30)
        self.batches.append([r.options.seed for r in requests])
        for step in range(1, 3):
            if progress is not None:
                progress(step, 2)
        if any(r.options.seed == 13 for r in requests):
            raise ValueError("bad request")
        return [GenerateResult(PolygonMesh.empty(), r.options, timings={"encoder": 0.0})
                for r in requests]


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, 60))


def test_requests_batch_by_sampler_settings_and_keep_their_seeds():
    async def scenario():
        fake = FakeGenerator()
        batcher = Batcher(fake.generate_batch, max_batch_size=3, max_delay_s=0.2, queue_size=8)
        batcher.start()
        seen: list[tuple[int, int]] = []
        jobs = [batcher.submit(request(s, steps=4 if s < 4 else 8),
                               progress=lambda d, t: seen.append((d, t))) for s in range(6)]
        outcomes = await asyncio.gather(*jobs)
        assert await batcher.close(5)
        return fake, outcomes, seen

    fake, outcomes, seen = run(scenario())
    assert [o.result.seed for o in outcomes] == list(range(6))
    assert sorted(map(sorted, fake.batches)) == [[0, 1, 2], [3], [4, 5]]
    assert {o.batch_size for o in outcomes[:3]} == {3}
    assert (2, 2) in seen


def test_a_failing_request_does_not_fail_its_batch():
    async def scenario():
        batcher = Batcher(FakeGenerator().generate_batch, max_batch_size=4, max_delay_s=0.2,
                          queue_size=8)
        batcher.start()
        results = await asyncio.gather(*(batcher.submit(request(s)) for s in (1, 13, 2)),
                                       return_exceptions=True)
        await batcher.close(5)
        return results

    ok1, bad, ok2 = run(scenario())
    assert isinstance(bad, ValueError)
    assert ok1.result.seed == 1 and ok2.result.seed == 2


def test_queue_full_and_close():
    gate = threading.Event()

    async def scenario():
        batcher = Batcher(FakeGenerator(gate).generate_batch, max_batch_size=1,
                          max_delay_s=0.0, queue_size=1)
        batcher.start()
        running = asyncio.ensure_future(batcher.submit(request(1)))
        while batcher.depth or not batcher.busy:  # wait until it left the queue
            await asyncio.sleep(0.01)
        queued = asyncio.ensure_future(batcher.submit(request(2)))
        await asyncio.sleep(0)
        with pytest.raises(QueueFull):
            await batcher.submit(request(3))
        assert batcher.retry_after() >= 1
        drained = await batcher.close(0.05)  # the gate holds the batch: not drained
        gate.set()
        with pytest.raises(ShuttingDown):
            await batcher.submit(request(4))
        return drained, await asyncio.gather(running, queued, return_exceptions=True)

    drained, results = run(scenario())
    assert drained is False
    assert all(isinstance(r, ShuttingDown) for r in results)


def test_close_waits_for_a_request_being_collected():
    async def scenario():
        batcher = Batcher(FakeGenerator().generate_batch, max_batch_size=4, max_delay_s=0.3,
                          queue_size=8)
        batcher.start()
        job = asyncio.ensure_future(batcher.submit(request(5)))
        await asyncio.sleep(0.02)  # the worker holds it, waiting for company
        drained = await batcher.close(10)
        return drained, await job

    drained, outcome = run(scenario())
    assert drained and outcome.result.seed == 5


def test_a_cancelled_request_leaves_the_queue():
    gate = threading.Event()

    async def scenario():
        batcher = Batcher(FakeGenerator(gate).generate_batch, max_batch_size=1,
                          max_delay_s=0.0, queue_size=4)
        batcher.start()
        running = asyncio.ensure_future(batcher.submit(request(1)))
        while batcher.depth or not batcher.busy:
            await asyncio.sleep(0.01)
        with pytest.raises(asyncio.TimeoutError):
            await asyncio.wait_for(batcher.submit(request(2)), 0.05)
        depth = batcher.depth
        gate.set()
        await running
        await batcher.close(5)
        return depth

    assert run(scenario()) == 0


def test_a_call_runs_alone_between_batches_and_stops_when_given_up():
    gate = threading.Event()

    async def scenario():
        fake = FakeGenerator(gate)
        batcher = Batcher(fake.generate_batch, max_batch_size=4, max_delay_s=0.0,
                          queue_size=8)
        batcher.start()
        calls: list[str] = []

        def work(progress):
            calls.append("ran")
            for step in (1, 2, 3):
                progress(step, 3)
            return "repaired"

        first = asyncio.ensure_future(batcher.submit(request(1)))
        while batcher.depth or not batcher.busy:  # the first batch holds the thread
            await asyncio.sleep(0.01)
        seen: list[tuple[int, int]] = []
        call = asyncio.ensure_future(batcher.submit_call(
            work, progress=lambda d, t: seen.append((d, t))))
        later = [asyncio.ensure_future(batcher.submit(request(s))) for s in (2, 3)]
        await asyncio.sleep(0.02)
        gate.set()
        outcome = await call
        await asyncio.gather(first, *later)

        started = threading.Event()

        def endless(progress):
            started.set()
            while True:
                progress(1, 1)

        given_up = asyncio.ensure_future(batcher.submit_call(endless))
        while not started.is_set():
            await asyncio.sleep(0.01)
        given_up.cancel()
        with pytest.raises(asyncio.CancelledError):
            await given_up
        await asyncio.sleep(0.05)  # the thread left the call at its next step

        def failing(progress):
            raise ValueError("bad region")

        with pytest.raises(ValueError, match="bad region"):
            await batcher.submit_call(failing)
        assert await batcher.close(5)
        return fake, outcome, seen, calls

    fake, outcome, seen, calls = run(scenario())
    assert outcome.result == "repaired" and outcome.batch_size == 1 and calls == ["ran"]
    assert seen == [(1, 3), (2, 3), (3, 3)]
    assert sorted(map(sorted, fake.batches)) == [[1], [2, 3]]  # never batched with the call


def test_an_explicit_key_decides_which_requests_batch():
    async def scenario():
        fake = FakeGenerator()
        batcher = Batcher(fake.generate_batch, max_batch_size=4, max_delay_s=0.2, queue_size=8)
        batcher.start()
        # the same sampler settings in the options, but two keys (e.g. two resolved starts)
        await asyncio.gather(*(batcher.submit(request(s), key="odd" if s % 2 else "even")
                               for s in range(4)))
        assert await batcher.close(5)
        return fake

    assert sorted(map(sorted, run(scenario()).batches)) == [[0, 2], [1, 3]]
