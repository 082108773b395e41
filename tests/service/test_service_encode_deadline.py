"""The encoding of a reply counts against the request's deadline (issue 37: cancellation
at every stage, encoding included), on a real server (tiny exported model).

The test holds the mesh's validation (:class:`~service_testing.HeldStage` on
``spacemesh_service.outputs.validate_mesh``) until the request's deadline has passed, so
the deadline always falls inside the encoding: the answer is 504 ``timeout``, the mesh is
never written (the checkpoint between validating and writing stops it), and the server
then answers the same request again.
"""

from __future__ import annotations

import httpx
import pytest
from service_testing import ADMIT_ALL, HeldStage, as_ply, mesh_file

from spacemesh.examples import icosphere

pytestmark = pytest.mark.slow

#: The server's deadline (s): the work before the encoding takes a fraction of it.
DEADLINE_S = 3.0


@pytest.fixture(scope="module")
def deadline_server(start_server, generator):
    return start_server(generator, request_timeout_s=DEADLINE_S, max_batch_delay_ms=0,
                        **ADMIT_ALL)


class Counted:
    """``function``, counting its calls."""

    def __init__(self, function) -> None:
        self.function = function
        self.calls = 0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        return self.function(*args, **kwargs)


def _generate(url: str, case) -> httpx.Response:
    return httpx.post(url + "/generate", params={"seed": case.good_seed, "format": "obj"},
                      files={"file": ("points.ply", as_ply(case.points))}, timeout=120)


def _repair(url: str) -> httpx.Response:
    region = '{"sphere": {"center": [0.0, 0.0, 1.0], "radius": 0.5}}'
    return httpx.post(url + "/repair", params={"format": "obj", "steps": 4},
                      files={"file": ("mesh.obj", mesh_file(icosphere(3), "obj"))},
                      data={"region": region}, timeout=120)


@pytest.mark.parametrize("route", ["generate", "repair"])
def test_a_reply_encoded_past_its_deadline_is_a_504_and_never_written(
        deadline_server, case, monkeypatch, route):
    import spacemesh_service.outputs as outputs

    send = (lambda: _generate(deadline_server.url, case)) if route == "generate" else (
        lambda: _repair(deadline_server.url))
    held = HeldStage(outputs.validate_mesh)
    written = Counted(outputs.export_mesh)
    monkeypatch.setattr(outputs, "validate_mesh", held)
    monkeypatch.setattr(outputs, "export_mesh", written)

    late = send()
    assert late.status_code == 504, late.text
    assert late.json()["type"].endswith("/timeout")
    assert held.held.is_set() and held.calls == 1  # the deadline fell in the encoding
    assert written.calls == 0  # the checkpoint stopped it before the mesh was written

    monkeypatch.undo()
    again = send()
    assert again.status_code == 200, again.text
    assert again.content.startswith((b"v ", b"#", b"o "))
