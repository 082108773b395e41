"""Connectivity-only runs on a base model (``spacemesh train --base``) and their export."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnxruntime")

from spacemesh.export.repository import export_run, load_trained_model  # noqa: E402
from spacemesh.nn.config import get_config  # noqa: E402
from spacemesh.nn.model import TorchBackend  # noqa: E402
from spacemesh.runtime.pipeline import MeshGenerator  # noqa: E402
from spacemesh.runtime.repository import ModelRepository  # noqa: E402
from spacemesh.topology import check_topology  # noqa: E402
from spacemesh.train.checkpoint import latest_checkpoint, load_checkpoint  # noqa: E402
from spacemesh.train.loop import TrainOptions, train  # noqa: E402
from tests.export.conftest import invoke_train  # noqa: E402
from tests.export.conftest import tiny_config as _config  # noqa: E402


def test_only_the_connectivity_network_trains(base_run):
    base, run = base_run
    state = load_checkpoint(latest_checkpoint(run))
    manifest = json.loads((base / "manifest.json").read_text())
    card = state["extra"]["base"]
    assert card["files"] == {f: e["sha256"] for f, e in manifest["files"].items()}
    assert not any(key.startswith("encoder.") for key in state["model"])
    # the base's encoder, diffusion and vertex count are inherited
    inherited = json.loads(json.dumps(state["config"].to_dict()))
    for key in ("encoder", "denoiser", "diffusion", "max_vertices"):
        assert inherited[key] == manifest["config"][key], key
    assert state["config"].connectivity == get_config("tiny").connectivity
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    assert rows and rows[-1]["train_edge"] and "train_epsilon" not in rows[-1]
    assert rows[-1]["val_edge_f1"]


def test_resume_keeps_the_base(toy_model, base_run, tmp_path):
    base, run = base_run
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    summary = train(TrainOptions(config=_config(), data=toy_model.data, out=copy, steps=3,
                                 resume=True, progress=False), log=lambda m: None)
    state = load_checkpoint(summary.checkpoint)
    assert state["step"] == 3 and state["extra"]["base"]["path"] == str(base.resolve())
    rows = list(csv.DictReader(open(copy / "metrics.csv")))
    assert "train_epsilon" not in rows[-1]


def test_export_copies_the_base_graphs_and_matches_torch(base_run, exported_base_run):
    base, run = base_run
    directory = exported_base_run
    for graph in ("encoder.onnx", "denoiser.onnx"):
        assert (directory / graph).read_bytes() == (base / graph).read_bytes()
    new, old = (directory / "connectivity.onnx").read_bytes(), (base / "connectivity.onnx")
    assert new != old.read_bytes()
    repo = ModelRepository.load(directory, threads=1)  # every sha256 checked
    training = repo.manifest["training"]
    assert training["steps"] == 0 and training["connectivity_steps"] > 0
    assert training["base"]["name"] == "spacemesh-tiny" and "base_training" in training
    assert repo.manifest["data"]["base"]["files"] == training["base"]["files"]
    assert str(directory.parent.parent) not in json.dumps(repo.manifest)  # no machine paths
    assert str(base.parent.parent) not in json.dumps(repo.manifest)
    model, _ = load_trained_model(run)
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 1, (2, 50, 3)).astype(np.float32)
    volumes = repo.backend.encode(points)
    vertices = rng.uniform(-1, 1, (2, 9, 3)).astype(np.float32)
    valid = rng.random((2, 9)) > 0.2
    ct = TorchBackend(model).connect(vertices, valid, volumes)
    co = repo.backend.connect(vertices, valid, volumes)
    for name in ("x", "root", "prev", "next"):
        assert np.allclose(getattr(ct, name), getattr(co, name), atol=1e-4), name
    result = MeshGenerator.from_repository(directory, threads=1).generate(
        rng.normal(size=(300, 3)), seed=0)
    assert check_topology(result.mesh).is_closed_oriented_manifold


def test_export_never_overwrites_its_base(base_run):
    base, run = base_run
    with pytest.raises(ValueError, match="base model"):
        export_run(run, base.parents[1], version=1, threads=1)
    assert (base / "manifest.json").is_file()


def test_a_changed_base_is_refused(toy_model, base_run, tmp_path):
    base, _run = base_run
    copy = tmp_path / "base"
    shutil.copytree(base, copy)
    run = tmp_path / "run"
    train(TrainOptions(config=_config(), data=toy_model.data, out=run, steps=1,
                       progress=False, base=copy), log=lambda m: None)
    with open(copy / "denoiser.onnx", "ab") as handle:
        handle.write(b"\0")
    with pytest.raises(ValueError, match=r"denoiser\.onnx"):
        export_run(run, tmp_path / "models", version=2, threads=1)
    with pytest.raises(ValueError, match=r"denoiser\.onnx"):
        train(TrainOptions(config=_config(), data=toy_model.data, out=run, steps=2,
                           resume=True, progress=False), log=lambda m: None)


def test_cli_refuses_a_missing_base_in_one_line(toy_model, tmp_path):
    result = invoke_train(toy_model, tmp_path / "run", "--base", str(tmp_path / "nowhere"))
    assert result.exit_code != 0
    assert "base model" in result.output and "Traceback" not in result.output
