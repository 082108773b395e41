"""Schemathesis against the real server's OpenAPI: no 5xx, and every error is a
conforming problem+json.

Every operation of ``/openapi.json`` gets its documented examples and a bounded,
reproducible number of generated requests (``derandomize=True``, ``max_examples``),
sent to the real server on loopback; a response must not be a server error, must match
the documented status codes, content types and schemas, and an error must be a problem
object (``type``, ``title``, ``status`` equal to the HTTP status, ``detail``).
"""

from __future__ import annotations

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis.errors import Unsatisfiable
from schemathesis import GenerationMode
from schemathesis.checks import (
    content_type_conformance,
    not_a_server_error,
    response_schema_conformance,
    status_code_conformance,
)

pytestmark = pytest.mark.slow

PROBLEM = "application/problem+json"
CHECKS = (not_a_server_error, status_code_conformance, content_type_conformance,
          response_schema_conformance)

#: Generated requests per operation and mode (positive and negative), and examples tried.
BOUNDED = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                   phases=[Phase.explicit, Phase.generate],
                   suppress_health_check=list(HealthCheck))


@pytest.fixture(scope="module")
def operations(server) -> list:
    """The operations of the served OpenAPI document, sent to the same server."""
    schema = schemathesis.openapi.from_url(server.url + "/openapi.json")
    found = [result.ok() for result in schema.get_all_operations()]
    assert {"/generate", "/repair"} <= {op.path for op in found}
    return found


def check(case) -> None:
    """One request: no 5xx, the documented responses, errors as problem objects."""
    response = case.call(timeout=60)
    case.validate_response(response, checks=CHECKS)
    if response.status_code >= 400:
        content_type = response.headers["content-type"]
        if isinstance(content_type, list):  # schemathesis keeps every value of a header
            content_type = content_type[0]
        assert content_type.startswith(PROBLEM), response.text
        body = response.json()
        assert body["type"].startswith("https://spacemesh.dev/problems/"), body
        assert body["status"] == response.status_code and body["title"] and body["detail"]


def test_the_documented_examples_get_documented_answers(operations):
    tried = 0
    for operation in operations:
        for strategy in operation.get_strategies_from_examples():
            given(strategy)(settings(BOUNDED, max_examples=1)(lambda case: check(case)))()
            tried += 1
    assert tried >= 2  # /generate and /repair document examples


@pytest.mark.parametrize("mode", [GenerationMode.POSITIVE, GenerationMode.NEGATIVE])
def test_generated_requests_get_no_server_error(operations, mode):
    fuzzed = set()
    for operation in operations:
        try:
            given(operation.as_strategy(mode))(BOUNDED(lambda case: check(case)))()
        except Unsatisfiable:  # nothing to break in an operation without inputs
            assert mode is GenerationMode.NEGATIVE and not operation.body, operation.label
            continue
        fuzzed.add(operation.path)
    assert {"/generate", "/repair"} <= fuzzed
