"""The tolerance search: the smallest vertex count whose distance is within tolerance."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from spacemesh.runtime.options import GenerateOptions, OptionError
from spacemesh.runtime.tolerance import (
    BRACKET_RATIO,
    MAX_SEARCH_VERTICES,
    MAX_TRIES,
    MIN_SEARCH_VERTICES,
    attempt_options,
    most_vertices,
    search_vertex_count,
)


@pytest.fixture(scope="module")
def toy_generator(toy_model):
    from spacemesh.runtime import MeshGenerator

    return MeshGenerator.from_repository(toy_model.repository, threads=1)


def made(distance_of_count):
    """A fake generate: its result's fit distance is ``distance_of_count(count)``."""
    calls = []

    def run(count):
        calls.append(count)
        fit = SimpleNamespace(points_to_mesh_mean_rel=distance_of_count(count))
        return SimpleNamespace(count=count, fit=fit)

    return run, calls


@pytest.mark.parametrize(("tolerance", "smallest"), [(0.01, 100), (0.002, 500), (0.05, 20)])
def test_the_search_brackets_the_smallest_count_that_meets_it(tolerance, smallest):
    run, calls = made(lambda n: 1.0 / n)
    result, met, tried = search_vertex_count(run, tolerance, 200)
    assert met and result.fit.points_to_mesh_mean_rel <= tolerance
    assert smallest <= result.count <= BRACKET_RATIO * smallest + 1
    assert len(calls) <= MAX_TRIES and [c for c, _ in tried] == calls
    assert len(set(calls)) == len(calls)  # no count is made twice


def test_an_unreachable_tolerance_returns_the_closest_mesh_unmet():
    run, calls = made(lambda n: 0.5 + 1.0 / n)
    result, met, tried = search_vertex_count(run, 0.01, 200)
    assert not met and result.count == max(calls) == MAX_SEARCH_VERTICES
    assert [c for c, _ in tried] == calls
    run, calls = made(lambda n: 0.0)
    result, met, _ = search_vertex_count(run, 0.01, 200)
    assert met and result.count == MIN_SEARCH_VERTICES


def test_the_search_tries_no_more_vertices_than_the_points():
    run, calls = made(lambda n: 0.5 + 1.0 / n)  # never met: the ladder climbs to the cap
    result, met, _ = search_vertex_count(run, 0.01, 200, most=most_vertices(2048))
    assert not met and result.count == max(calls) == 2048
    run, calls = made(lambda n: 1.0 / n)  # met at 1,000: bracketed below the cap
    result, met, _ = search_vertex_count(run, 0.001, 200, most=most_vertices(2048))
    assert met and 1000 <= result.count <= 2048 and max(calls) <= 2048
    assert most_vertices(3) == MIN_SEARCH_VERTICES
    assert most_vertices(200_000) == MAX_SEARCH_VERTICES


def test_a_distance_that_is_not_monotone_or_not_finite_still_ends():
    run, calls = made(lambda n: 0.001 if n % 3 else 0.02)
    result, met, _ = search_vertex_count(run, 0.01, 200)
    assert met and result.count % 3 and len(calls) <= MAX_TRIES
    run, calls = made(lambda n: float("nan"))
    result, met, _ = search_vertex_count(run, 0.01, 200)
    assert not met and len(calls) <= MAX_TRIES


def test_tries_ask_for_a_count_instead_of_the_tolerance():
    options = GenerateOptions(seed=4, start="points", tolerance=0.01, samples=2)
    assert attempt_options(options, 300) == GenerateOptions(seed=4, start="points",
                                                            target_vertices=300, samples=2)


@pytest.mark.parametrize(("fields", "message"), [
    ({"tolerance": 0.0}, "tolerance must be in"),
    ({"tolerance": float("nan")}, "tolerance must be in"),
    ({"tolerance": "loose"}, "tolerance must be a number"),
    ({"tolerance": True}, "tolerance must be a number"),
    ({"tolerance": 0.01, "target_vertices": 100}, "cannot both be set"),
    ({"tolerance": 0.01, "start": "noise"}, "needs start=points"),
])
def test_bad_tolerances_name_the_option(toy_generator, fields, message):
    with pytest.raises(OptionError, match=message) as info:
        GenerateOptions(**fields).resolve(toy_generator.spec)
    assert info.value.option == "tolerance"


def test_a_tolerance_request_prepares_its_points_once_for_all_tries(toy_generator):
    import numpy as np

    from spacemesh.runtime import GenerateRequest, MeshGenerator

    class Counting(MeshGenerator):
        prepared = 0

        def prepare_input(self, request, options=None):
            Counting.prepared += 1
            return super().prepare_input(request, options)

    generator = Counting(toy_generator.backend, toy_generator.spec)
    points = np.random.default_rng(3).normal(size=(400, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    options = GenerateOptions(seed=1, steps=2, tolerance=0.02)
    [result] = generator.generate_batch([GenerateRequest(points, None, options)])
    assert len(result.tolerance_tries) >= 2  # the search ran more than one generate
    assert Counting.prepared == 1
    assert result.fit.tolerance == 0.02 and result.options.target_vertices is None


def test_a_tolerance_search_checks_topology_on_the_count_it_found(toy_generator):
    from dataclasses import replace

    import numpy as np

    from spacemesh.runtime import GenerateRequest, MeshGenerator

    stages = []
    retrying = MeshGenerator(toy_generator.backend, replace(toy_generator.spec, retry_seeds=2))
    points = np.random.default_rng(4).normal(size=(400, 3))
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    options = GenerateOptions(seed=1, steps=2, tolerance=0.02)
    [result] = retrying.generate_batch([GenerateRequest(points, None, options)],
                                       stage=lambda name, d, t: stages.append(name))
    assert result.fit.points_pieces >= 1 and result.fit.tolerance == 0.02
    # the first try is a whole generate (the model's retries when its seed fails the
    # check); the search's tries run without them, and the count found gets them once,
    # after the last try
    tries = [i for i, s in enumerate(stages) if s == "tolerance"]
    pieces = [i for i, s in enumerate(stages) if s == "pieces"]
    assert len(tries) == len(result.tolerance_tries) >= 2  # the toy's first try misses
    assert len([i for i in pieces if i < tries[1]]) <= 1
    assert not [i for i in pieces if tries[1] < i < tries[-1]]
    assert len([i for i in pieces if i > tries[-1]]) <= 1
    assert result.fit.tolerance_met == (result.fit.points_to_mesh_mean_rel <= 0.02)


@pytest.fixture(scope="module")
def shipped_generator(shipped):
    from spacemesh.runtime import MeshGenerator

    return MeshGenerator.from_repository(shipped.path, threads=1)


def test_a_tolerance_is_met_by_one_decode_simplified_to_it(shipped_generator):
    """With the shipped model, a torus's points within a tolerance take one generate:
    its decode, fitted, collapsed for as long as the points stay within the aim; a
    looser tolerance gives fewer vertices, and the mesh is as valid as any other."""
    import numpy as np

    from spacemesh.examples import torus_grid
    from spacemesh.geometry.intersections import self_intersection_fraction
    from spacemesh.primitives import sample_surface
    from spacemesh.runtime.tolerance import aim
    from tests.validity import assert_valid_mesh

    points, _ = sample_surface(torus_grid(32, 16), 2048, np.random.default_rng(0))
    counts = []
    for tolerance in (0.01, 0.003):
        stages: list[str] = []
        result = shipped_generator.generate(points, seed=0, tolerance=tolerance,
                                            stage=lambda name, d, t, into=stages:
                                            into.append(name))
        assert stages.count("tolerance") == 1 and len(result.tolerance_tries) == 1
        assert result.fit.points_to_mesh_mean_rel <= aim(tolerance)
        assert result.fit.tolerance_met and result.options.tolerance == tolerance
        simplified = result.geometry_stats["simplify"]
        assert simplified["collapsed"] > 0 and 1 <= simplified["tries"] <= 3
        assert_valid_mesh(result.mesh)
        assert self_intersection_fraction(result.mesh) == 0.0
        counts.append(result.mesh.n_vertices)
    assert counts[0] < counts[1] < 400  # below the dense decode's count
