"""Every problem type the real server answers becomes its typed exception, over REST and
gRPC alike; the classes mirror ``spacemesh_service.problems`` one to one."""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh_client import errors as E
from spacemesh_service import problems as P

pytestmark = pytest.mark.slow


def test_every_problem_type_of_the_service_has_its_class():
    assert set(P.KINDS) <= set(E.PROBLEM_TYPES)
    for slug, kind in P.KINDS.items():
        cls = E.PROBLEM_TYPES[slug]
        assert cls.slug == slug and kind.type == E.TYPE_BASE + slug
        assert cls.retryable == (kind.status in (429, 503)), slug
    assert E.TYPE_BASE == P.TYPE_BASE and E.PROBLEM_MEDIA_TYPE == P.PROBLEM_MEDIA_TYPE


def test_region_error_kinds_have_classes():
    region = pytest.importorskip("spacemesh.repair.region")
    assert set(region.ERROR_KINDS) <= set(E.PROBLEM_TYPES)
    assert all(issubclass(E.PROBLEM_TYPES[k], E.RegionError) for k in region.ERROR_KINDS)


def test_unknown_types_are_the_base_class():
    error = E.error_from_problem({"type": "https://example.com/teapot", "title": "Teapot",
                                  "status": 418, "detail": "short and stout", "tea": 1})
    assert type(error) is E.SpaceMeshError
    assert (error.type, error.status, error.detail, error.extra) == (
        "https://example.com/teapot", 418, "short and stout", {"tea": 1})
    assert type(E.error_from_http(502, {}, b"<html>Bad Gateway</html>")) is E.SpaceMeshError
    proxy = E.error_from_http(503, {"Retry-After": "7"}, b"busy")
    assert type(proxy) is E.Unavailable and proxy.retry_after == 7.0 and proxy.retryable
    assert type(E.error_from_http(429, {}, b"")) is E.RateLimited


def expect(client, cls, points, **kwargs):
    with pytest.raises(cls) as caught:
        client.generate(points, **kwargs)
    error = caught.value
    assert type(error) is cls, repr(error)
    assert error.type == E.TYPE_BASE + cls.slug and error.detail
    return error


def test_input_errors(client, case):
    rng = np.random.default_rng(2)
    limit = expect(client, E.TooFewPoints, case.points[:10])
    assert limit.status == 422
    expect(client, E.TooManyPoints, rng.standard_normal((5001, 3)))
    nan = case.points.copy()
    nan[5, 2] = np.nan
    expect(client, E.NonFinite, nan)
    flat = np.hstack([rng.standard_normal((40, 2)), np.full((40, 1), 3.0)])
    assert "coplanar" in expect(client, E.DegenerateGeometry, flat).detail
    expect(client, E.InvalidNormals, case.points, normals=case.points[:5])
    assert expect(client, E.InvalidOption, case.points, format="stl").extra["option"] == (
        "format")  # every option error is one kind (422 invalid-option)
    assert expect(client, E.InvalidOption, case.points, steps=100_000).extra["option"] == (
        "steps")
    expect(client, E.MalformedInput, b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n",
           filename="c.ply")
    expect(client, E.UnsupportedFormat, bytes(range(256)) * 10, filename="c.docx")
    expect(client, E.PayloadTooLarge, b"0 0 0\n" * 400_000, filename="c.xyz")
    assert isinstance(limit, E.InvalidRequest)


def test_rest_problems_carry_their_extension_members(rest_url, case):
    from spacemesh_client import Client, RetryPolicy

    with Client(rest_url, retry=RetryPolicy.never()) as client:
        error = expect(client, E.TooFewPoints, case.points[:10])
    assert error.extra == {"limit": 16, "points": 10} and error.instance == "/generate"
    assert error.title == P.TOO_FEW_POINTS.title


def test_no_surface(client, case):
    error = expect(client, E.NoSurface, case.points, **case.no_surface)
    assert not isinstance(error, E.InvalidRequest)


def test_model_not_found_and_repair(rest_url, grpc_url, case):
    # repair's own errors: tests/client/test_client_repair.py
    from spacemesh_client import Client, RetryPolicy

    with Client(rest_url, retry=RetryPolicy.never()) as client:
        with pytest.raises(E.ModelNotFound) as caught:
            client.model_info("no-such-model")
        assert caught.value.status == 404 and isinstance(caught.value, E.NotFound)
        mesh = client.generate(case.points, seed=case.good_seed, format="obj")
    for url in (rest_url, grpc_url):
        with Client(url, retry=RetryPolicy.never()) as client:
            try:  # a generated mesh: repaired, or its region refused (e.g. grows to all)
                repaired = client.repair(mesh, [0], steps=4)
            except E.RegionError as error:
                assert error.status == 422
            else:
                assert repaired.stats.closed and repaired.repair["requested_faces"] == 1
    with Client(grpc_url, retry=RetryPolicy.never()) as client:
        with pytest.raises(E.Unimplemented, match="REST"):
            client.model_info()


def test_local_mistakes_are_ordinary_python_errors(client, tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        client.generate(tmp_path / "missing.ply")
    with pytest.raises(TypeError):
        client.generate(object())
    with pytest.raises(ValueError, match="normals"):
        client.generate(tmp_path / "missing.ply", normals=[[0, 0, 1]])


def test_too_expensive_names_the_option_over_both_transports(start_server, generator, case):
    from spacemesh_client import Client, RetryPolicy

    server = start_server(generator, warmup=False, request_budget_s=5)
    for url in (server.url, "grpc://" + server.grpc_target):
        with Client(url, retry=RetryPolicy(attempts=3)) as client:
            error = expect(client, E.TooExpensive, case.points, start="points",
                           target_vertices=10_000)
        assert error.status == 422 and not error.retryable, url
        assert isinstance(error, E.InvalidRequest)
        assert error.extra["option"] == "target_vertices", (url, error.extra)
        assert "lower target_vertices" in error.detail
