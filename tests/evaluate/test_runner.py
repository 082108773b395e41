"""The evaluation runner and report, with a stand-in for the model (fast)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from spacemesh.examples import cube_quads, icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface

pytest.importorskip("pymeshlab")

from spacemesh.evaluate import (
    EvalShape,
    GalleryRow,
    render_gallery,
    run_evaluation,
    write_report,
)

PNG = b"\x89PNG\r\n\x1a\n"


class HullModel:
    """Stands in for ``MeshGenerator``: the convex hull of the points (a valid mesh)."""

    name = "hull"
    spec = SimpleNamespace(normals=False)

    def __init__(self):
        self.calls = []

    def generate(self, points, normals=None, *, seed=0, steps=None):
        self.calls.append((len(points), normals, seed, steps))
        hull = ConvexHull(points[::8])
        tri = hull.simplices.copy()
        v = hull.points
        a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
        inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - v.mean(axis=0)) < 0
        tri[inward] = tri[inward][:, ::-1]
        mesh, _ = PolygonMesh.from_faces(v, tri).remove_unreferenced_vertices()
        return SimpleNamespace(mesh=mesh)


def make_shapes():
    shapes = []
    for i, (name, mesh) in enumerate(
        (("cube", cube_quads(3.0)), ("sphere", icosphere(2)), ("torus", torus_grid(16, 8)))
    ):
        points, _ = sample_surface(mesh, 2048, np.random.default_rng(i))
        shapes.append(EvalShape(name, mesh, points, "example"))
    return shapes


@pytest.fixture(scope="module")
def result():
    model = HullModel()
    out = run_evaluation(
        make_shapes(),
        generator=model,
        baselines=("psr_star", "bpa"),
        seed=5,
        steps=3,
        gallery=2,
        progress=False,
    )
    out.config["calls"] = model.calls
    return out


def test_every_method_is_scored_on_every_shape(result):
    assert len(result.rows) == 3 * 4
    assert [r["method"] for r in result.rows[:4]] == ["ours", "psr_star", "bpa", "gt"]
    assert all(r["status"] == "ok" for r in result.rows)
    assert [c[2:] for c in result.config["calls"]] == [(5, 3)] * 3  # seed and steps passed
    assert all(c[1] is None for c in result.config["calls"])  # this model reads no normals
    ours = [r for r in result.rows if r["method"] == "ours"]
    assert all(r["valid"] for r in ours)
    gt = [r for r in result.rows if r["method"] == "gt"]
    assert all(r["edge_length_w1"] == 0 and r["cd"] < 3e-3 for r in gt)
    # PSR* is decimated to our vertex count for the same shape
    for mine, star in zip(ours, [r for r in result.rows if r["method"] == "psr_star"], strict=True):
        assert abs(star["n_vertices"] - mine["n_vertices"]) <= 0.1 * mine["n_vertices"] + 2


def test_a_failing_method_is_a_row_not_a_crash():
    class Broken(HullModel):
        def generate(self, points, normals=None, *, seed=0, steps=None):
            raise RuntimeError("boom")

    out = run_evaluation(
        make_shapes()[:1], generator=Broken(), baselines=(), gallery=1, progress=False
    )
    ours = out.rows[0]
    assert ours["status"].startswith("failed: RuntimeError: boom") and not ours["valid"]
    assert np.isnan(ours["cd"]) and out.gallery[0].meshes["ours"] is None
    with pytest.raises(ValueError, match="psr_star_target"):
        run_evaluation(make_shapes()[:1], psr_star_target="half", progress=False)
    with pytest.raises(ValueError, match="unknown baselines"):
        run_evaluation(make_shapes()[:1], baselines=("nope",), progress=False)


def test_report_files(result, tmp_path):
    paths = write_report(result, tmp_path, title="test", command="spacemesh eval ...")
    table = paths["table"].read_text()
    assert "| Ours |" in table and "| PSR* |" in table and "| GT (resampled) |" in table
    assert "spacemesh eval ..." in table
    assert len(paths["csv"].read_text().splitlines()) == 1 + 12
    summary = json.loads(paths["summary"].read_text())
    assert summary["summary"]["ours"]["valid"] == 1.0
    for key in ("histograms", "gallery"):
        assert paths[key].read_bytes()[:8] == PNG


def test_gallery_renders_points_meshes_and_failures(tmp_path):
    cube = cube_quads(2.0)
    cube = cube.with_vertices(cube.vertices - 1.0)
    row = GalleryRow(
        "cube",
        np.random.default_rng(0).uniform(-1, 1, (100, 3)),
        {"ours": cube, "psr_star": None, "gt": cube},
    )
    path = render_gallery([row], tmp_path / "g.png")
    assert path.read_bytes()[:8] == PNG


def test_true_normals_reach_the_true_baselines_and_the_normals_mode():
    """psr_true reads the shape's own normals (here turned inward, so its surface comes
    out inside-out while PSR* from estimated normals does not), ``normals`` passes them
    to our pipeline, and a shape without true normals gets a failed row, not a crash."""
    mesh = icosphere(3)
    points, normals = sample_surface(mesh, 2048, np.random.default_rng(0))
    inward = EvalShape("inward", mesh, points, "example", -normals)
    bare = EvalShape("bare", mesh, points, "example")
    model = HullModel()
    out = run_evaluation(
        [inward, bare], generator=model, modes=("default", "normals"),
        baselines=("psr_star", "psr_true", "psr_true_gt"), gallery=0, progress=False,
    )
    rows = {(r["shape_id"], r["method"]): r for r in out.rows}
    assert [r["method"] for r in out.rows[:6]] == [
        "ours", "ours_normals", "psr_star", "psr_true", "psr_true_gt", "gt"]
    assert model.calls[0][1] is None
    np.testing.assert_allclose(model.calls[1][1], -normals)
    assert rows["bare", "ours_normals"]["status"] == "failed: no true normals"
    assert rows["bare", "psr_true"]["status"] == "failed: no true normals"
    assert rows["bare", "psr_star"]["status"] == "ok"
    assert rows["inward", "psr_star"]["oriented"] and rows["inward", "psr_true"]["status"] == "ok"
    assert rows["inward", "psr_true_gt"]["n_vertices"] <= mesh.n_vertices + 2
    assert abs(rows["inward", "psr_true"]["n_vertices"] - rows["inward", "ours"]["n_vertices"]) \
        <= 0.1 * rows["inward", "ours"]["n_vertices"] + 2
    # IN: the share of inaccurate normals, about all of them on an inside-out surface
    assert rows["inward", "psr_star"]["in"] < 0.1 < 0.9 < rows["inward", "psr_true"]["in"]


def test_corrupt_points_appends_uniform_outliers_in_the_bounding_box():
    from spacemesh.evaluate.runner import corrupt_points

    points, _ = sample_surface(icosphere(2), 1000, np.random.default_rng(3))
    noisy = corrupt_points(points, outliers=0.05, seed=[0, 1])
    assert noisy.shape == (1050, 3)
    np.testing.assert_array_equal(noisy[:1000], points)  # the surface points are kept
    extra = noisy[1000:]
    assert (extra >= points.min(axis=0)).all() and (extra <= points.max(axis=0)).all()
    # off the sphere: most outliers are far from the unit surface
    assert np.mean(np.abs(np.linalg.norm(extra, axis=1) - 1.0) > 0.1) > 0.5
    np.testing.assert_array_equal(corrupt_points(points, outliers=0.05, seed=[0, 1]), noisy)
