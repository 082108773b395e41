"""A real KServe v2 client (Triton's ``tritonclient.http``) against the real server:
health and metadata read correctly, and our errors reach it as its exception with our
message (problem bodies on the ``/v2`` routes carry the KServe ``error`` member)."""

from __future__ import annotations

import pytest

from tests.deploy.deploy_testing import missing

try:
    import tritonclient.http as httpclient
    from tritonclient.utils import InferenceServerException
except ImportError:  # a check tool (deploy/requirements-check.txt)
    httpclient = InferenceServerException = None


@pytest.fixture(scope="module")
def triton(server):
    if httpclient is None:
        missing("tritonclient[http]")  # skipped here, a failure in CI
    client = httpclient.InferenceServerClient(url=server.url.removeprefix("http://"),
                                              connection_timeout=30, network_timeout=60)
    yield client
    client.close()


def test_health_and_metadata_read_correctly(triton, server, http):
    name = server.server.engine.model_name
    version = server.server.engine.model_version
    assert triton.is_server_live() is True
    assert triton.is_server_ready() is True
    assert triton.is_model_ready(name) is True
    assert triton.get_server_metadata() == http.get("/v2").json()
    meta = triton.get_model_metadata(name)
    assert meta == http.get(f"/v2/models/{name}").json()
    assert meta["name"] == name and meta["versions"] == [version]
    assert [i["name"] for i in meta["inputs"]] == ["points", "normals"]
    assert triton.get_model_metadata(name, model_version=version) == meta


def test_an_unknown_model_raises_with_our_message(triton, server):
    name = server.server.engine.model_name
    with pytest.raises(InferenceServerException) as caught:
        triton.get_model_metadata("no-such-model")
    error = caught.value
    assert error.status() == "404"
    assert error.message() == ("No such model or version: no model no-such-model; this "
                               f"server has {name} version "
                               f"{server.server.engine.model_version}")
    assert "exception occurred in the client" not in str(error)
    with pytest.raises(InferenceServerException, match=r"no model .* version 99") as caught:
        triton.get_model_metadata(name, model_version="99")
    assert caught.value.status() == "404"
    assert triton.is_model_ready("no-such-model") is False


def test_a_route_we_do_not_serve_raises_with_our_message(triton, server):
    """Inference over KServe v2 is not offered (``/generate`` is): the client's request
    gets a problem whose ``error`` it reads."""
    import numpy as np

    points = httpclient.InferInput("points", [4, 3], "FP64")
    points.set_data_from_numpy(np.zeros((4, 3)))
    with pytest.raises(InferenceServerException) as caught:
        triton.infer(server.server.engine.model_name, [points])
    assert caught.value.status() in ("404", "405")
    assert caught.value.message().startswith(("No such resource: ", "Method not allowed: "))


def test_only_the_v2_routes_add_the_member(http):
    v2 = http.get("/v2/models/no-such-model")
    assert v2.headers["content-type"].startswith("application/problem+json")
    body = v2.json()
    assert body["error"] == f"{body['title']}: {body['detail']}"
    other = http.get("/v2x/no-such-route")  # outside /v2: the problem alone
    assert other.status_code == 404 and "error" not in other.json()
    assert other.json()["type"].endswith("/not-found")
