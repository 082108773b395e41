"""The onnxruntime pipeline: frames, orientation, batching, seeds, progress, errors."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("onnxruntime")

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import flip_faces, signed_volume
from spacemesh.runtime import GenerateRequest, MeshGenerator
from spacemesh.runtime.network import drop_duplicates
from spacemesh.runtime.options import GenerateOptions, OptionError
from spacemesh.runtime.request import normalize_points
from spacemesh.topology import check_topology


@pytest.fixture(scope="module")
def generator(toy_model):
    return MeshGenerator.from_repository(toy_model.repository, threads=1)


@pytest.fixture(scope="module")
def cloud():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(400, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_results_are_valid_outward_meshes_with_timings(generator, cloud):
    result = generator.generate(cloud, seed=3, start="noise")
    mesh = result.mesh
    if mesh.n_faces:
        assert check_topology(mesh).is_closed_oriented_manifold
        # outward: a non-negative volume, up to rounding for a mesh that encloses none
        # (the tiny model can return a flat one; it is oriented in the normalised frame)
        extent = float(np.ptp(mesh.vertices, axis=0).max())
        assert signed_volume(mesh) >= -1e-9 * extent**3
    assert set(result.timings) == {"encoder", "sampler", "connectivity", "extraction",
                                   "geometry", "report", "total"}
    assert result.steps == generator.spec.steps and result.method == generator.spec.method
    assert result.fit is not None and result.sample_scores == [(3, result.fit.score)]


def test_timings_cover_every_seed_the_request_ran(generator, cloud):
    """``samples=3`` runs three seeds: the result's timings are their sum (each seed's
    share of the shared network calls, its own decode, geometry and report), and the
    stages add up to the total."""
    from spacemesh.runtime.request import summed_timings

    three = generator.generate(cloud, seed=0, samples=3, start="noise")
    stages = {k: v for k, v in three.timings.items() if k != "total"}
    assert three.timings["total"] == pytest.approx(sum(stages.values()))
    assert len(three.sample_scores) == 3
    fake = [type("R", (), {"timings": {"geometry": 1.0, "total": 2.0}})(),
            type("R", (), {"timings": {"geometry": 0.5, "total": 1.5, "report": 0.25}})()]
    assert summed_timings(fake) == {"geometry": 1.5, "total": 3.5, "report": 0.25}


def test_output_is_in_the_input_frame(generator, cloud):
    base = generator.generate(cloud, seed=2)
    moved = generator.generate(cloud * 7.5 + [100.0, -3.0, 2.0], seed=2)
    assert moved.mesh.face_key_set() == base.mesh.face_key_set()
    assert np.allclose(moved.mesh.vertices, base.mesh.vertices * 7.5 + [100.0, -3.0, 2.0],
                       atol=1e-4)


def test_batch_equals_single_requests_and_seeds_matter(generator, cloud):
    requests = [GenerateRequest(cloud, options=GenerateOptions(seed=s, start="noise"))
                for s in (0, 1)]
    requests.append(GenerateRequest(cloud * 2, options=GenerateOptions(
        seed=0, steps=3, sampler="ddpm", start="noise")))
    requests.append(GenerateRequest(cloud, options=GenerateOptions(seed=4, start="points",
                                                                   start_time=0.2)))
    requests.append(GenerateRequest(cloud, options=GenerateOptions(seed=4, samples=2)))
    batch = generator.generate_batch(requests)
    for request, result in zip(requests, batch, strict=True):
        alone = generator.generate(request.points, options=request.options)
        assert alone.mesh.face_key_set() == result.mesh.face_key_set()
        assert np.allclose(alone.mesh.vertices, result.mesh.vertices, atol=1e-5)
    assert batch[2].steps == 3 and batch[2].method == "ddpm"
    assert batch[0].mesh.face_key_set() != batch[1].mesh.face_key_set()


def test_progress_is_reported_for_every_step(generator, cloud):
    seen = []
    generator.generate(cloud, seed=0, steps=4, start="noise",
                       progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    seen.clear()  # from the points at half the diffusion: the lower half of the steps
    generator.generate(cloud, seed=0, steps=4, start="points", start_time=0.5,
                       progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 2), (2, 2)]


def test_bad_requests_are_refused(generator, cloud):
    with pytest.raises(ValueError):
        generator.generate(np.zeros((10, 2)))
    with pytest.raises(ValueError):
        generator.generate(np.zeros((0, 3)))
    with pytest.raises(ValueError):
        generator.generate(np.full((5, 3), np.nan))
    with pytest.raises(ValueError):
        generator.generate(cloud, normals=np.zeros((3, 3)))
    bad = [("steps", {"steps": 0}), ("sampler", {"sampler": "euler"}),
           ("start", {"start": "mesh"}), ("start_time", {"start": "noise", "start_time": 0.1}),
           ("start_time", {"start": "points", "start_time": 1.5}),
           ("start_time", {"start": "points", "start_time": float("nan")}),
           ("target_vertices", {"target_vertices": 3}),
           ("target_vertices", {"target_vertices": 20000}),
           ("target_vertices", {"start": "noise", "target_vertices": 100}),
           ("samples", {"samples": 0}), ("samples", {"samples": 17}),
           ("seed", {"seed": -1}), ("raw", {"raw": "maybe"}), ("steps", {"steps": 2.5})]
    for option, fields in bad:
        with pytest.raises(OptionError) as caught:
            generator.generate(cloud, **fields)
        assert caught.value.option == option, fields


def test_helpers():
    p = np.array([[0.0, 0, 0], [4, 2, 0], [2, 1, 1]])
    unit, centre, scale = normalize_points(p)
    assert scale == 2.0 and np.allclose(centre, [2, 1, 0.5])
    assert np.allclose(unit.max(0) - unit.min(0), [2, 1, 0.5])
    assert normalize_points(np.ones((3, 3)))[2] == 1.0
    tetra = PolygonMesh.from_faces([*np.eye(3).tolist(), [0, 0, 0]],
                                   [[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]])
    flipped = flip_faces(tetra)
    assert signed_volume(flipped) == pytest.approx(-signed_volume(tetra))
    assert flip_faces(flipped).face_key_set() == tetra.face_key_set()
    positions = np.array([[0.0, 0, 0], [0, 0, 1e-6], [1, 1, 1], [0.5, 0, 0]])
    alive = drop_duplicates(positions, np.array([True, True, True, False]))
    assert alive.tolist() == [True, False, True, False]


def test_vertex_spacing_thins_the_sampled_vertices(generator, cloud):
    from dataclasses import replace

    spec = generator.spec
    assert spec.vertex_spacing == generator.repository.manifest["sampler"].get(
        "vertex_spacing", 1e-4)
    dense = generator.generate(cloud, seed=3, start="noise")
    try:
        generator.spec = replace(spec, vertex_spacing=0.5)
        sparse = generator.generate(cloud, seed=3, start="noise")
        generator.spec = replace(spec, vertex_spacing=10.0)  # one vertex survives
        single = generator.generate(cloud, seed=3, start="noise")
    finally:
        generator.spec = spec
    assert sparse.n_sampled_vertices < dense.n_sampled_vertices
    assert single.n_sampled_vertices == 1 and single.mesh.n_faces == 0


def test_points_start_budget_raw_and_samples(generator, cloud):
    """start=points: the count is the target (or the model's default) whatever the
    seed; the seed still changes the mesh; raw skips the geometry stage; samples keeps
    the best-fitting seed, which samples=1 at that seed reproduces."""
    counts = {generator.generate(cloud, seed=s, start="points", raw=True).n_sampled_vertices
              for s in (0, 1, 2)}
    assert counts == {min(generator.spec.vertices, len(cloud))}
    a = generator.generate(cloud, seed=0, start="points", target_vertices=120)
    b = generator.generate(cloud, seed=1, start="points", target_vertices=120)
    assert a.mesh.face_key_set() != b.mesh.face_key_set()
    for result in (a, b):
        if result.mesh.n_faces:
            assert check_topology(result.mesh).is_closed_oriented_manifold
            assert abs(result.mesh.n_vertices - 120) <= 12
    raw = generator.generate(cloud, seed=0, start="points", target_vertices=120, raw=True)
    assert raw.geometry_stats == {} and a.geometry_stats
    best = generator.generate(cloud, seed=5, start="points", samples=3)
    scores = dict(best.sample_scores)
    assert sorted(scores) == [5, 6, 7]
    assert scores[best.seed] == min(scores.values())
    again = generator.generate(cloud, seed=best.seed, start="points")
    assert again.mesh.face_key_set() == best.mesh.face_key_set()
    assert again.fit.score == pytest.approx(best.fit.score)


def test_the_seed_whose_pieces_agree_with_the_points_wins_over_a_closer_fit():
    from dataclasses import replace
    from types import SimpleNamespace

    from spacemesh.examples import icosphere
    from spacemesh.geometry import PointFacts, fit_report
    from spacemesh.runtime.choice import best_fit as _best_fit

    sphere = icosphere(1)
    base = fit_report(sphere, sphere.vertices, PointFacts(pieces=1, outliers=0.0, noise=0.0))

    def tried(seed, pieces, score, crossing=0.0):
        fit = replace(base, pieces=pieces, self_intersections=crossing,
                      points_to_mesh_mean_rel=score, mesh_to_points_mean_rel=0.0)
        return SimpleNamespace(seed=seed, fit=fit)

    options = GenerateOptions(seed=5, samples=3)
    results = [tried(5, 2, 0.010), tried(6, 1, 0.012), tried(7, 1, 0.011)]
    winner = _best_fit(results, options, expected_pieces=1)
    assert winner.seed == 7 and winner.options.seed == 7
    assert winner.fit.points_pieces == 1 and winner.fit.pieces_agree
    assert "points_pieces" in winner.fit.to_dict()
    assert "points_pieces" not in fit_report(sphere, sphere.vertices).to_dict()
    assert winner.sample_scores == [(5, 0.010), (6, 0.012), (7, 0.011)]
    # none agrees: the closest fit
    assert _best_fit(results, options, expected_pieces=3).seed == 5
    # without the check (a model without retry_seeds): the closest fit alone
    assert _best_fit(results, options, expected_pieces=1, check=False).seed == 5
    # then faces that do not cross win over a closer fit
    crossing = [tried(5, 1, 0.010, 0.02), tried(6, 1, 0.012), tried(7, 2, 0.009)]
    assert _best_fit(crossing, options, expected_pieces=1).seed == 6


def test_a_model_with_retry_seeds_tries_more_when_no_mesh_is_acceptable(generator, cloud):
    from dataclasses import replace

    from spacemesh.geometry.pieces import point_pieces
    from spacemesh.runtime.choice import acceptable

    retrying = MeshGenerator(generator.backend, replace(generator.spec, retry_seeds=3))
    stages = []
    result = retrying.generate(cloud, seed=3, stage=lambda name, d, t: stages.append(name))
    plain = generator.generate(cloud, seed=3)
    expected = point_pieces(retrying.prepare_input(GenerateRequest(cloud, None)).cloud[:, :3])
    if acceptable(plain, expected):  # seed 3 was enough: nothing more ran
        assert result.sample_scores == plain.sample_scores and "pieces" not in stages
    else:  # seeds 4, 5, 6 ran too, and the winner is one of the four
        assert [seed for seed, _ in result.sample_scores] == [3, 4, 5, 6]
        assert "pieces" in stages and result.seed in (3, 4, 5, 6)
        assert result.options.seed == result.seed
    assert retrying.generate(cloud, seed=3).mesh.face_key_set() == result.mesh.face_key_set()
    # a winner that still crossed was untangled: clean, or at least less crossed
    if "untangle_rounds" in result.geometry_stats:
        stats = result.geometry_stats
        assert "untangle" in stages and stats["crossing_after"] < stats["crossing_before"]
        # then fitted to the points again, whose guard lets nothing cross again
        assert "untangle_refit_kept" in stats
        assert result.fit.self_intersections <= stats["crossing_after"]
        assert check_topology(result.mesh).is_closed_oriented_manifold


def test_retry_seeds_top_a_request_up_to_one_more_than_their_count(generator, cloud):
    from dataclasses import replace

    spec = replace(generator.spec, retry_seeds=3)
    assert [spec.retries_for(k) for k in (1, 2, 3, 4, 8)] == [3, 2, 1, 0, 0]
    assert replace(spec, retry_seeds=0).retries_for(1) == 0
    retrying = MeshGenerator(generator.backend, spec)
    for samples, most in ((2, 4), (4, 4)):
        stages = []
        result = retrying.generate(cloud, seed=3, samples=samples,
                                   stage=lambda name, d, t, seen=stages: seen.append(name))
        seeds = [seed for seed, _ in result.sample_scores]
        # the request's own seeds, then (only if none passed the check) up to 4 in all
        assert seeds[:samples] == list(range(3, 3 + samples))
        assert seeds == list(range(3, 3 + len(seeds))) and len(seeds) in (samples, most)
        assert ("pieces" in stages) == (len(seeds) > samples)


def test_retry_seeds_in_a_manifest_are_checked():
    from spacemesh.runtime.spec import check_retry_seeds

    assert check_retry_seeds(4) == 4
    for bad in (-1, 9, 2.0, True, "4"):
        with pytest.raises(ValueError, match="retry_seeds"):
            check_retry_seeds(bad)


def test_outliers_are_set_aside_before_anything_else_and_reported(generator, cloud):
    stray = np.array([[3.0, 3.0, 3.0], [-4.0, 2.5, 0.0], [0.5, -3.5, 2.0]])  # (3, 3)
    request = GenerateRequest(np.concatenate([cloud, stray]),
                              options=GenerateOptions(seed=1, start="points"))
    prepared = generator.prepare_input(request, request.options.resolve(generator.spec))
    assert prepared.quality is not None and not prepared.quality.kept[-3:].any()
    assert len(prepared.points) == len(cloud) + 3 - int((~prepared.quality.kept).sum())
    assert np.abs(prepared.points).max() <= 1.0 + 1e-9  # the frame is the sphere's
    result = generator.generate(request.points, seed=1, start="points")
    fit = result.fit
    assert fit is not None and fit.points_outliers == pytest.approx(
        (~prepared.quality.kept).mean())
    assert fit.points_noise is not None and 0.0 <= fit.points_noise < 0.01
    assert fit.n_points == len(prepared.points)  # measured from the kept points
    # nothing reaches for the strays (the toy model may make an empty mesh)
    assert result.mesh.n_vertices == 0 or np.abs(result.mesh.vertices).max() < 1.5
