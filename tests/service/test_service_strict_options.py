"""Strict options on a real server (uvicorn and gRPC on loopback, the tiny exported model).

Every option parses one way (``spacemesh.runtime.options.parse_value``) over every REST
form: query, multipart form, JSON body, and the streaming routes. Integer options take
only integer text, so ``seed=1e3``, ``seed=1.0``, ``samples=2.0`` and
``target_vertices=500.0`` are a 422 ``invalid-option`` naming the option (they were a
500, a ``TypeError`` in the pipeline, and a 400 with Python's own text). Names a route
does not take (unknown, or generate-only options sent to ``/repair``) are refused the
same way, while everything the web page and the SDK send is accepted.
"""

from __future__ import annotations

import json

import pytest
from service_testing import REPAIR_STEPS, as_text, mesh_file

from spacemesh.examples import icosphere

pytestmark = pytest.mark.slow

PROBLEM = "application/problem+json"
INVALID_OPTION = "https://spacemesh.dev/problems/invalid-option"
#: Integral floats and exponents for integer options: refused, never converted.
NOT_INTEGERS = [
    ({"seed": "1e3"}, "seed"),
    ({"seed": "1.0"}, "seed"),
    ({"start": "points", "samples": "2.0"}, "samples"),
    ({"start": "points", "target_vertices": "500.0"}, "target_vertices"),
]
#: The same as JSON numbers (``1e3`` is a float in JSON too).
NOT_INTEGER_NUMBERS = [
    ({"seed": 1e3}, "seed"),
    ({"seed": 1.0}, "seed"),
    ({"start": "points", "samples": 2.0}, "samples"),
    ({"start": "points", "target_vertices": 500.0}, "target_vertices"),
]
GENERATE_ROUTES = ["/generate", "/generate/stream"]
REPAIR_ROUTES = ["/repair", "/repair/stream"]


@pytest.fixture(scope="module")
def cloud(case):
    return case.points[::2]  # 150 points


@pytest.fixture(scope="module")
def mesh_upload():
    return {"file": ("m.obj", mesh_file(icosphere(1)))}


def assert_invalid_option(response, *names: str) -> dict:
    """A 422 ``invalid-option`` problem+json naming ``names[0]`` (and every name in the
    detail); never a 500, never a stream."""
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith(PROBLEM), response.headers
    body = response.json()
    assert body["type"] == INVALID_OPTION and body["status"] == 422, body
    assert body["option"] == names[0], body
    for name in names:
        assert name in body["detail"], body
    assert "Traceback" not in body["detail"] and "invalid literal" not in body["detail"]
    return body


def post_generate(http, route: str, where: str, cloud, options: dict):
    """``POST route`` with ``options`` in the query, the multipart form or the JSON body."""
    if where == "query":
        return http.post(route, params=options, json={"points": cloud.tolist()})
    if where == "form":
        return http.post(route, files={"file": ("c.xyz", as_text(cloud))},
                         data={k: str(v) for k, v in options.items()})
    return http.post(route, json={"points": cloud.tolist(), **options})


# ---------------------------------------------------------------------- integers
@pytest.mark.parametrize("route", GENERATE_ROUTES)
@pytest.mark.parametrize("where", ["query", "form", "json"])
@pytest.mark.parametrize(("options", "name"), NOT_INTEGERS, ids=lambda v: str(v))
def test_integral_floats_are_not_integers(http, cloud, route, where, options, name):
    body = assert_invalid_option(post_generate(http, route, where, cloud, options), name)
    assert "must be an integer" in body["detail"]
    assert repr(options[name]) in body["detail"]  # the value as sent


@pytest.mark.parametrize("route", GENERATE_ROUTES)
@pytest.mark.parametrize(("options", "name"), NOT_INTEGER_NUMBERS, ids=lambda v: str(v))
def test_json_floats_are_not_integers(http, cloud, route, options, name):
    body = assert_invalid_option(post_generate(http, route, "json", cloud, options), name)
    assert "must be an integer" in body["detail"]


@pytest.mark.parametrize("route", REPAIR_ROUTES)
@pytest.mark.parametrize("where", ["query", "form"])
@pytest.mark.parametrize("options", [{"seed": "1e3"}, {"steps": "2.0"}], ids=str)
def test_repair_integers_too(http, mesh_upload, route, where, options):
    region = {"region": '{"faces": [0, 1, 2]}'}
    if where == "query":
        response = http.post(route, params=options, files=mesh_upload, data=region)
    else:
        response = http.post(route, files=mesh_upload, data={**region, **options})
    assert "must be an integer" in assert_invalid_option(response, *options)["detail"]


def test_integer_text_reaches_the_generator_as_an_integer(http, cloud, case):
    """Signs and surrounding spaces are integer text; the reply reports the parsed
    values (typed: the JSON format has them as numbers)."""
    params = {"seed": f" +{case.good_seed} ", "samples": "2", "start": "points",
              "target_vertices": "60", "format": "json"}
    response = http.post("/generate", params=params, json={"points": cloud.tolist()})
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["samples"] == 2 and body["target_vertices"] == 60
    assert body["sample_scores"][0]["seed"] == case.good_seed  # the first seed tried
    assert response.headers["x-spacemesh-samples"] == "2"


# ---------------------------------------------------------------------- unknown names
@pytest.mark.parametrize("route", GENERATE_ROUTES)
@pytest.mark.parametrize("where", ["query", "form", "json"])
def test_unknown_options_are_refused(http, cloud, route, where):
    response = post_generate(http, route, where, cloud, {"colour": "red", "seed": 1})
    body = assert_invalid_option(response, "colour")
    assert body["unknown"] == ["colour"]
    assert "seed" in body["detail"]  # the route's options are listed


def test_every_unknown_name_is_named(http, cloud):
    response = http.post("/generate", params={"zeta": 1, "alpha": 2},
                         json={"points": cloud.tolist()})
    assert assert_invalid_option(response, "alpha", "zeta")["unknown"] == ["alpha", "zeta"]


def test_an_option_sent_as_a_file_is_refused(http, mesh_upload):
    """(``/generate`` takes one file part, so there a second one is a 400 before this.)"""
    files = {**mesh_upload, "seed": ("seed.txt", b"7")}
    response = http.post("/repair", files=files, data={"region": '{"faces": [0, 1, 2]}'})
    assert "text field" in assert_invalid_option(response, "seed")["detail"]


@pytest.mark.parametrize("route", REPAIR_ROUTES)
@pytest.mark.parametrize("where", ["query", "form"])
@pytest.mark.parametrize("options", [{"tolerance": "0.01"}, {"target_vertices": "60"},
                                     {"samples": "2", "tolerance": "0.01"}], ids=str)
def test_generate_only_options_are_refused_by_repair(http, mesh_upload, route, where,
                                                     options):
    region = {"region": '{"faces": [0, 1, 2]}'}
    if where == "query":
        response = http.post(route, params=options, files=mesh_upload, data=region)
    else:
        response = http.post(route, files=mesh_upload, data={**region, **options})
    names = sorted(options)
    body = assert_invalid_option(response, *names)
    assert body["unknown"] == names
    assert "an option of /generate only" in body["detail"]


def test_unknown_repair_options_are_refused(http, mesh_upload):
    response = http.post("/repair", params={"colour": "red"}, files=mesh_upload,
                         data={"region": '{"faces": [0, 1, 2]}'})
    assert assert_invalid_option(response, "colour")["unknown"] == ["colour"]


def test_one_status_for_every_option_error(http, cloud, mesh_upload):
    """``format``, ``weld`` and ``max_growth`` errors are option errors too."""
    assert_invalid_option(post_generate(http, "/generate", "query", cloud,
                                        {"format": "stl"}), "format")
    for options, name in (({"weld": "maybe"}, "weld"), ({"max_growth": "2"}, "max_growth"),
                          ({"max_growth": "nan"}, "max_growth")):
        response = http.post("/repair", params=options, files=mesh_upload,
                             data={"region": '{"faces": [0, 1, 2]}'})
        assert_invalid_option(response, name)


# ---------------------------------------------------------------------- what we send
def test_what_the_web_page_sends_is_accepted(http, cloud, case):
    """The page's forms (service/spacemesh_service/static/app.js ``generateForm`` and
    ``repairForm``): the file, the options it offers as text, and ``format``."""
    form = {"seed": str(case.good_seed), "steps": "4", "start": "points",
            "start_time": "0", "raw": "false", "format": "json"}
    with http.stream("POST", "/generate/stream", files={"file": ("c.xyz", as_text(cloud))},
                     data=form) as response:
        response.read()
    assert response.status_code == 200, response.text
    assert "event: result" in response.text
    repair_form = {"region": json.dumps({"faces": [0, 1, 2]}), "seed": "1",
                   "steps": str(REPAIR_STEPS), "sampler": "ddim", "weld": "false",
                   "max_growth": "0.25", "format": "json"}
    with http.stream("POST", "/repair/stream",
                     files={"file": ("m.obj", mesh_file(icosphere(1)))},
                     data=repair_form) as response:
        response.read()
    assert response.status_code == 200, response.text
    assert "event: result" in response.text


def test_what_the_sdk_sends_is_accepted(server, cloud, case):
    from spacemesh_client import Client

    with Client(server.url) as client:
        mesh = client.generate(cloud, seed=case.good_seed, samples=2, start="points",
                               target_vertices=60, format="obj")
        assert mesh.options["samples"] == 2
        fixed = client.repair(mesh_file(icosphere(1)), {"faces": [0, 1, 2]}, seed=1,
                              steps=REPAIR_STEPS, weld=True, max_growth=0.25,
                              filename="m.obj", format="obj")
        assert fixed.stats.closed
