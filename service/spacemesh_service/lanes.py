"""Two lanes of work, so that a heavy request never holds up small ones.

Every generate and repair is costed before it is queued (:mod:`spacemesh.runtime.cost`).
One whose estimate fits the light lane's budget (``--light-lane-s``, a quarter of the
request deadline by default, and ``--light-lane-mb``) waits and runs in the **light**
lane; every other one in the **main** lane. Each lane is a
:class:`~spacemesh_service.batcher.Batcher`: its own bounded queue, batching and
inference thread. While a request of minutes holds the main lane, small requests go on
being answered in the light one; the two share the cores (and the networks' item pool,
:class:`spacemesh.runtime.backend.OnnxBackend`), never a queue. With ``--light-lane-s 0``
there is one lane, the main one, as before the lanes.

Lanes never change a mesh: a request's mesh depends on neither its batch nor the thread
that runs it (:mod:`spacemesh.runtime.backend`).
"""

from __future__ import annotations

import asyncio

from spacemesh.runtime.budget import Budget
from spacemesh.runtime.cost import Estimate
from spacemesh_service.batcher import Batcher, RunBatch
from spacemesh_service.metrics import Metrics


class Lanes:
    """The light and the main lane of one engine.

    Parameters
    ----------
    run : callable
        ``run(requests, progress=fn) -> results`` (``MeshGenerator.generate_batch``),
        shared by both lanes.
    light : Budget, optional
        What a request of the light lane may be estimated to cost (None: one lane).
    max_batch_size, max_delay_s, queue_size : see :class:`Batcher`
        Per lane.
    metrics : Metrics, optional
    """

    def __init__(self, run: RunBatch, *, light: Budget | None, max_batch_size: int,
                 max_delay_s: float, queue_size: int, metrics: Metrics | None = None) -> None:
        self.light_budget = light
        self.metrics = metrics

        def lane(name: str) -> Batcher:
            return Batcher(run, max_batch_size=max_batch_size, max_delay_s=max_delay_s,
                           queue_size=queue_size, metrics=metrics, lane=name)

        self.main = lane("main")
        self.light = lane("light") if light is not None else None

    @property
    def all(self) -> list[Batcher]:
        """Every lane, the light one first."""
        return [lane for lane in (self.light, self.main) if lane is not None]

    def start(self) -> None:
        """Start every lane's worker (call from the event loop)."""
        for lane in self.all:
            lane.start()

    def for_cost(self, estimate: Estimate) -> Batcher:
        """The lane of a request estimated at ``estimate``, counted in
        ``spacemesh_lane_requests_total``.

        Parameters
        ----------
        estimate : Estimate

        Returns
        -------
        Batcher
        """
        light = (self.light is not None and self.light_budget is not None
                 and self.light_budget.fits(estimate.seconds, estimate.memory_mb))
        chosen = self.light if light and self.light is not None else self.main
        if self.metrics is not None:
            self.metrics.lane_requests.labels(chosen.lane).inc()
        return chosen

    @property
    def depth(self) -> int:
        """Requests waiting in every lane."""
        return sum(lane.depth for lane in self.all)

    @property
    def busy(self) -> bool:
        """Whether any request waits or runs in any lane."""
        return any(lane.busy for lane in self.all)

    def overload(self, deadline_s: float) -> str | None:
        """Why new work would not be done within ``deadline_s`` in some lane (None: it
        would in both): :meth:`Batcher.overload` of each lane, named.

        Parameters
        ----------
        deadline_s : float

        Returns
        -------
        str or None
        """
        for lane in self.all:
            reason = lane.overload(deadline_s)
            if reason is not None:
                return f"{lane.lane} lane: {reason}" if self.light is not None else reason
        return None

    async def close(self, timeout: float) -> bool:
        """Close every lane at once (:meth:`Batcher.close`).

        Returns
        -------
        bool
            True when every request finished in time.
        """
        done = await asyncio.gather(*(lane.close(timeout) for lane in self.all))
        return all(done)


__all__ = ["Lanes"]
