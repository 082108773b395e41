"""A repair past its deadline stops inside the stage it is in (issue 37: a repair of
326,000 faces ran 33 s past its 30 s limit), on a real server (tiny exported model).

Each test wraps a function that one stage of a repair calls on every round of its loop
(:class:`HeldStage`): its first call waits until the request's deadline has passed, so
the deadline always falls inside that stage, then every later call counts whether it
began after the work was abandoned. The stage must stop at its next checkpoint
(:func:`spacemesh.cancel.checkpoint`): at most two more calls, where the unstopped
repair makes dozens (counted on these requests: ``CALLS``). The request answers 504,
the lane counts a stopped call (the planning, in a parse thread, frees its slot), and
the server then repairs again.
"""

from __future__ import annotations

import importlib
import json

import httpx
import numpy as np
import pytest
from service_testing import ADMIT_ALL, HeldStage, mesh_file, metric, wait_for

from spacemesh.examples import icosphere
from tests.repair.auto_meshes import punched

pytestmark = pytest.mark.slow

#: The server's deadline (s): the stages before the held one take a fraction of it.
DEADLINE_S = 3.0


def holes_mesh():
    """An icosphere of 1,031 faces with 12 holes (7 regions, 8 model passes)."""
    rng = np.random.default_rng(0)
    centres = rng.normal(size=(12, 3))
    return punched(icosphere(3), (centres / np.linalg.norm(centres, axis=1,
                                                           keepdims=True)).tolist(), 0.2)


HOLES = {"auto": "holes"}
MARKED = {"sphere": {"center": [0.0, 0.0, 1.0], "radius": 0.5}}
#: stage -> (module, function it calls every round, region, steps, calls of the
#: unstopped repair).
STAGES = {
    "cut": ("spacemesh.repair.auto", "hole_loops", HOLES, 4, 14),  # planning, per hole
    "passes": ("spacemesh.repair.api", "plan_repair", HOLES, 4, 8),  # per model pass
    "sampler": ("spacemesh.repair.inpaint", "reverse_step", MARKED, 64, 64),
    "splice": ("spacemesh.repair.splice", "_match", HOLES, 4, 37),
    "geometry": ("spacemesh.geometry.fitting", "fit_energy_terms", HOLES, 4, 96),
    "fairing": ("spacemesh.repair.fill.fairing", "fair_positions", HOLES, 4, 304),
    "refinement": ("spacemesh.repair.fill.refine", "_split_pass", HOLES, 4, 99),
    "probes": ("spacemesh.repair.fill.probe", "faces_touching", HOLES, 4, 203),
}


@pytest.fixture(scope="module")
def deadline_server(start_server, generator):
    return start_server(generator, request_timeout_s=DEADLINE_S, max_batch_delay_ms=0,
                        **ADMIT_ALL)


def repair(url: str, mesh, region: dict, steps: int) -> httpx.Response:
    return httpx.post(url + "/repair", params={"format": "obj", "steps": steps},
                      files={"file": ("mesh.obj", mesh_file(mesh, "obj"))},
                      data={"region": json.dumps(region)}, timeout=120)


@pytest.mark.parametrize("stage", list(STAGES))
def test_a_repair_past_its_deadline_stops_inside_each_stage(deadline_server, monkeypatch,
                                                            stage):
    module_name, name, region, steps, unstopped = STAGES[stage]
    module = importlib.import_module(module_name)
    held = HeldStage(getattr(module, name))
    monkeypatch.setattr(module, name, held)
    url = deadline_server.url
    stopped = metric(url, "spacemesh_stopped_batches_total")
    mesh = holes_mesh() if region is HOLES else icosphere(3)

    late = repair(url, mesh, region, steps)
    assert late.status_code == 504, late.text
    assert late.json()["type"].endswith("/timeout")
    engine = deadline_server.server.engine
    if stage == "cut":  # planned in a parse thread: it stops and frees its slot
        wait_for(lambda: engine.parsing.running == 0, "the planning to stop")
    else:
        wait_for(lambda: metric(url, "spacemesh_stopped_batches_total") == stopped + 1,
                 "the lane to stop the repair")
    assert held.held.is_set()  # the deadline fell inside this stage
    assert held.after <= 2, (held.after, unstopped)  # the next checkpoint stopped it
    assert held.calls < unstopped

    monkeypatch.undo()
    again = repair(url, icosphere(3), MARKED, 4)
    assert again.status_code == 200, again.text
