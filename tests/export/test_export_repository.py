"""The model repository: layout, manifest, and integrity checks."""

from __future__ import annotations

import json
import shutil

import pytest

pytest.importorskip("onnxruntime")

from spacemesh.runtime.repository import (
    ModelRepository,
    ModelRepositoryError,
    resolve_version_dir,
)


def test_layout_and_manifest(toy_model):
    version = toy_model.repository
    assert version.name == "1" and version.parent.name == "spacemesh-tiny"
    manifest = json.loads((version / "manifest.json").read_text())
    for key in ("config", "inputs", "schedule", "sampler", "embedding", "graphs", "files",
                "onnx", "data", "training", "metrics"):
        assert key in manifest, key
    assert set(manifest["files"]) == {"encoder.onnx", "denoiser.onnx", "connectivity.onnx"}
    assert manifest["onnx"]["opset"] >= 20
    assert len(manifest["schedule"]["betas"]) == manifest["schedule"]["timesteps"]
    assert manifest["embedding"]["adjacency_dim"] == manifest["config"]["connectivity"][
        "adjacency_dim"]
    assert manifest["data"]["source"] == "toy" and manifest["training"]["steps"] > 0
    assert "edge_f1" in manifest["metrics"]["validation"]
    assert not list(version.glob("*.data"))  # weights are inside the .onnx files
    assert resolve_version_dir(version.parent) == version
    assert resolve_version_dir(version.parent.parent) == version


def test_sha256_mismatch_and_missing_files_are_refused(toy_model, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(toy_model.repository, copy)
    ModelRepository.load(copy, intra_op_threads=1)
    with open(copy / "denoiser.onnx", "ab") as handle:
        handle.write(b"\0")
    with pytest.raises(ModelRepositoryError, match=r"denoiser\.onnx.*sha256"):
        ModelRepository.load(copy)
    (copy / "denoiser.onnx").unlink()
    with pytest.raises(ModelRepositoryError, match="missing"):
        ModelRepository.load(copy)
    with pytest.raises(ModelRepositoryError, match="does not exist"):
        ModelRepository.load(tmp_path / "nowhere")
    (copy / "manifest.json").write_text("{}")
    with pytest.raises(ModelRepositoryError, match="not a spacemesh-model"):
        ModelRepository.load(copy)


def test_vertex_spacing_is_calibrated_on_the_val_split(toy_model, tmp_path):
    from spacemesh.export.repository import calibrate_vertex_spacing
    from spacemesh.runtime.pipeline import ModelSpec

    found = calibrate_vertex_spacing(toy_model.repository, toy_model.data, shapes=3,
                                     threads=1, grid=(1e-4, 0.1, 10.0))
    assert found["grid"] == [1e-4, 0.1, 10.0] and len(found["chamfer_mean"]) == 3
    assert found["empty"][2] == 1.0  # one vertex left: never a surface
    assert found["vertex_spacing"] in (1e-4, 0.1)  # an all-empty spacing cannot win
    assert "val split" in found["calibration"]
    # the runtime reads the field from the manifest, with the old default when absent
    copy = tmp_path / "repo"
    shutil.copytree(toy_model.repository, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    assert ModelSpec.from_manifest(manifest).vertex_spacing == 1e-4
    manifest["sampler"]["vertex_spacing"] = 0.05
    assert ModelSpec.from_manifest(manifest).vertex_spacing == 0.05


def test_the_decode_section_follows_the_training_style(toy_model):
    from spacemesh.export.repository import decode_section
    from spacemesh.runtime.pipeline import ModelSpec

    manifest = json.loads((toy_model.repository / "manifest.json").read_text())
    assert manifest["decode"]["max_sides"] is None  # the toy data card names no style
    assert ModelSpec.from_manifest(manifest).decode.max_sides is None
    assert decode_section({"style": "qem"})["max_sides"] == 3
    assert decode_section({"style": "isotropic"})["max_sides"] == 3
    assert decode_section({"style": "quad"})["max_sides"] is None
    manifest["decode"] = decode_section({"style": "qem"})
    assert ModelSpec.from_manifest(manifest).decode.max_sides == 3
    del manifest["decode"]  # repositories written before the section existed
    assert ModelSpec.from_manifest(manifest).decode.max_sides is None
