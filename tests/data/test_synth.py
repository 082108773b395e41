"""Synthetic generation: every style, determinism across worker counts, resume, reading."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from spacemesh.data.shards import SPLITS, MeshRecord, first_records, open_dataset
from spacemesh.data.synth import SynthConfig, make_shape, synthesize
from spacemesh.data.validate import validate_mesh
from spacemesh.primitives import triangulate_faces

trimesh = pytest.importorskip("trimesh")

SMALL = {"vertex_min": 32, "vertex_max": 96, "points": 64, "shard_size": 4}


def independent_check(record: MeshRecord) -> None:
    """Closed, manifold, outward: trimesh and a vertex-link walk on the triangulated mesh."""
    triangles, _ = triangulate_faces(record.mesh)
    tm = trimesh.Trimesh(record.mesh.vertices, triangles, process=False)
    assert tm.is_watertight
    assert tm.is_winding_consistent
    assert tm.volume > 0
    assert len(tm.split(only_watertight=False)) == 1
    # Vertex-manifold: the link of every vertex (the far sides of its triangles) is one cycle.
    link: dict[int, dict[int, int]] = {}
    for a, b, c in triangles.tolist():
        for v, x, y in ((a, b, c), (b, c, a), (c, a, b)):
            assert x not in link.setdefault(v, {})
            link[v][x] = y
    for ring in link.values():
        start = cur = next(iter(ring))
        for _ in range(len(ring)):
            cur = ring[cur]
        assert cur == start and len({*ring}) == len(ring)
        seen, cur = set(), start
        while cur not in seen:
            seen.add(cur)
            cur = ring[cur]
        assert len(seen) == len(ring)


@pytest.mark.parametrize(
    ("style", "count"), [("qem", 4), ("planar", 4), ("isotropic", 2), ("quad", 2), ("farthest", 3)]
)
def test_styles_make_valid_shapes(style, count):
    vmin = 8 if style == "planar" else SMALL["vertex_min"]
    config = SynthConfig(
        count=count, seed=3, style=style, vertex_min=vmin, vertex_max=96, points=64
    )
    made, degrees = 0, set()
    for index in range(count):
        shape, _, _ = make_shape(config, index)
        if shape is None:
            continue
        made += 1
        mesh = shape["mesh"]
        assert validate_mesh(mesh) == []
        assert vmin <= mesh.n_vertices <= 96
        assert np.isclose(np.abs(mesh.vertices).max(axis=0).max(), 1.0, atol=1e-6)
        z, y, x = mesh.vertices[:, 2], mesh.vertices[:, 1], mesh.vertices[:, 0]
        assert np.all(np.lexsort((x, y, z)) == np.arange(mesh.n_vertices))
        assert shape["points"].shape == (64, 3) and shape["points"].dtype == np.float32
        assert np.allclose(np.linalg.norm(shape["normals"], axis=1), 1.0, atol=1e-5)
        degrees.update(mesh.degree_histogram())
    assert made >= count - 1
    if style in ("planar", "quad"):
        assert max(degrees) >= 4


@pytest.fixture(scope="module")
def dataset_pair(tmp_path_factory) -> tuple[Path, Path, SynthConfig]:
    root = tmp_path_factory.mktemp("synth")
    config = SynthConfig(count=10, seed=7, style="qem", **SMALL)
    synthesize(config, root / "one", workers=1, progress=False)
    synthesize(config, root / "two", workers=2, progress=False)
    return root / "one", root / "two", config


def test_same_seed_same_bytes_any_worker_count(dataset_pair):
    one, two, _ = dataset_pair
    names = sorted(p.name for p in one.iterdir())
    assert names == sorted(p.name for p in two.iterdir())
    assert [n for n in names if n.startswith("shard-")] == [f"shard-0000{k}.npz" for k in range(3)]
    for name in names:
        assert (one / name).read_bytes() == (two / name).read_bytes(), name


def test_manifest(dataset_pair):
    one, _, config = dataset_pair
    manifest = json.loads((one / "manifest.json").read_text())
    assert manifest["seed"] == 7 and manifest["style"] == "qem"
    assert manifest["vertex_range"] == [config.vertex_min, config.vertex_max]
    assert manifest["counts"]["stored"] + len(manifest["failed_indices"]) == 10
    assert sum(manifest["splits"].values()) == manifest["counts"]["stored"]
    assert all(len(s["sha256"]) == 64 for s in manifest["shards"])
    assert "generator_version" in manifest and isinstance(manifest["rejections"], dict)


def test_resume_rewrites_only_missing_shard(dataset_pair, tmp_path):
    one, _, config = dataset_pair
    copy = tmp_path / "copy"
    shutil.copytree(one, copy)
    (copy / "shard-00001.npz").unlink()
    before = (copy / "shard-00000.npz").stat().st_mtime_ns
    synthesize(config, copy, workers=1, progress=False)
    assert (copy / "shard-00000.npz").stat().st_mtime_ns == before
    for name in ("shard-00001.npz", "manifest.json"):
        assert (copy / name).read_bytes() == (one / name).read_bytes()


def test_other_parameters_refused(dataset_pair, tmp_path):
    one, _, _ = dataset_pair
    copy = tmp_path / "copy"
    shutil.copytree(one, copy)
    other = SynthConfig(count=10, seed=8, style="qem", **SMALL)
    with pytest.raises(ValueError, match="other parameters"):
        synthesize(other, copy, workers=1, progress=False)


def test_open_dataset_and_independent_check(dataset_pair):
    one, _, _ = dataset_pair
    dataset = open_dataset(one)
    assert len(dataset) == json.loads((one / "manifest.json").read_text())["counts"]["stored"]
    by_split = sum(len(open_dataset(one, split)) for split in SPLITS)
    assert by_split == len(dataset)
    for record in dataset:
        assert isinstance(record, MeshRecord)
        assert record.points.shape == (64, 3) and record.normals.dtype == np.float32
        assert record.split in SPLITS and record.style == "qem" and record.genus >= 0
        assert isinstance(record.features["concave_sharp"], bool)
        independent_check(record)
    assert dataset[-1].shape_id == dataset[len(dataset) - 1].shape_id
    with pytest.raises(ValueError):
        open_dataset(one, "training")
    # the first shapes that fit a model's tokens, in storage order
    cap = int(np.median([r.mesh.n_vertices for r in dataset]))
    fitting = [r.shape_id for r in dataset if r.mesh.n_vertices <= cap]
    assert [r.shape_id for r in first_records(one, max_vertices=cap, limit=3)] == fitting[:3]
    val = [r.shape_id for r in open_dataset(one, "val")]
    assert [r.shape_id for r in first_records(one, "val", max_vertices=10**6, limit=99)] == val


@pytest.mark.parametrize("missing", ["manifold3d", "pymeshlab"])
def test_synth_without_the_geometry_extra_is_one_line(tmp_path, missing):
    """Without the geometry extra, ``data synth`` once stored 0 shapes and exited 0 (each
    attempt's ImportError counted as a rejected shape); now it names the install command."""
    script = (f"import sys; sys.modules[{missing!r}] = None; "  # the import fails
              "from spacemesh.cli import main; main()")
    done = subprocess.run([sys.executable, "-c", script, "data", "synth", "--out",
                           str(tmp_path / "d"), "--count", "2", "--no-progress"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stdout + done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
    assert missing in done.stderr and "pip install 'spacemesh[geometry]'" in done.stderr
    assert not (tmp_path / "d").exists()
