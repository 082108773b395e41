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
    ModelRepository.load(copy, threads=1)
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
    from spacemesh.runtime.spec import ModelSpec

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
    from spacemesh.geometry.policy import decode_section
    from spacemesh.runtime.spec import ModelSpec

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


def test_the_decode_section_of_qem_models_refines_and_flips_flat_quads():
    from spacemesh.geometry.policy import (
        FIT_GAIN,
        FLAT_FLIP_DEGREES,
        decode_changes,
        decode_section,
    )

    new = decode_section({"style": "qem", "generator_version": "1.1.0"})
    assert new["reinsert"] and new["flip"]
    assert new["flat_delaunay_degrees"] == FLAT_FLIP_DEGREES
    # generator 1.0.0 left QEM's arbitrary diagonals in flat quads: no Delaunay rule
    assert decode_section({"style": "qem", "generator_version": "1.0.0"})[
        "flat_delaunay_degrees"] is None
    assert decode_section({"style": "isotropic", "generator_version": "1.1.0"})[
        "flat_delaunay_degrees"] is None
    assert not decode_section({"style": "quad"})["reinsert"]
    # every triangle model flips toward the conditioning points; polygons are kept
    assert new["fit_gain"] == FIT_GAIN
    assert decode_section({"style": "isotropic"})["fit_gain"] == FIT_GAIN
    assert decode_section({"style": "quad"})["fit_gain"] is None
    options = decode_changes(new)
    assert options == {"max_sides": 3, "reinsert": True, "flip": True,
                       "flat_delaunay_degrees": FLAT_FLIP_DEGREES, "fit_gain": FIT_GAIN}


@pytest.mark.parametrize("version", [1, 7])
def test_shipped_versions_decode_as_their_manifests_say(version):
    from pathlib import Path

    from spacemesh.geometry.policy import DECODE_KEYS, decode_section
    from spacemesh.runtime.spec import ModelSpec

    path = Path(__file__).resolve().parents[2] / "models/spacemesh-small" / str(version)
    manifest = json.loads((path / "manifest.json").read_text())
    decode = ModelSpec.from_manifest(manifest).decode
    section = manifest.get("decode")
    if section is None:  # version 1 predates the section: every field keeps its default
        assert all(getattr(decode, key) in (None, False) for key in DECODE_KEYS)
        return
    assert {key: getattr(decode, key) for key in DECODE_KEYS} == {
        key: section[key] for key in DECODE_KEYS}
    # the policy, now in spacemesh.geometry, still writes what these versions shipped
    assert decode_section(manifest["data"]) == section


def test_a_model_version_is_repackaged_with_todays_decode(toy_model, tmp_path):
    from typer.testing import CliRunner

    from spacemesh.cli import _register
    from spacemesh.cli.common import app
    from spacemesh.runtime.pipeline import MeshGenerator

    _register()
    old = json.loads((toy_model.repository / "manifest.json").read_text())
    result = CliRunner().invoke(app, ["export", str(toy_model.repository), "--out",
                                      str(tmp_path), "--version", "7", "--eval-data",
                                      str(toy_model.data), "--eval-shapes", "3",
                                      "--pipeline-shapes", "2", "--threads", "1"])
    assert result.exit_code == 0, result.output
    new_dir = tmp_path / old["name"] / "7"
    new = json.loads((new_dir / "manifest.json").read_text())
    assert new["version"] == 7 and new["derived_from"]["version"] == old["version"]
    assert new["files"] == old["files"]  # the graphs, byte for byte
    for file in old["files"]:
        assert (new_dir / file).read_bytes() == (toy_model.repository / file).read_bytes()
    held = new["metrics"]["heldout"]
    assert held["connectivity_on_gt_vertices"]["shapes"] == 3
    assert held["pipeline"]["shapes"] == 2 and held["pipeline"]["valid"] == 1.0
    assert MeshGenerator.from_repository(new_dir).spec.decode.max_sides == new["decode"][
        "max_sides"]
    # the source version itself cannot be the target, and a corrupted graph is refused
    again = CliRunner().invoke(app, ["export", str(new_dir), "--out", str(tmp_path),
                                     "--version", "7"])
    assert again.exit_code != 0 and "is the source" in again.output
    (new_dir / "encoder.onnx").write_bytes(b"not onnx")
    broken = CliRunner().invoke(app, ["export", str(new_dir), "--out", str(tmp_path),
                                      "--version", "8"])
    assert broken.exit_code != 0 and "sha256" in broken.output


def test_an_empty_val_split_to_calibrate_on_is_one_line(toy_model, tmp_path):
    """``export --calibrate-data`` with no val shapes once failed with numpy's "need at
    least one array to concatenate"; exporting a run and repackaging a version both say
    what is wrong, on one line, exit code 2, before writing anything."""
    import subprocess
    import sys

    from spacemesh.data.shards import open_dataset
    from spacemesh.train.toy import make_toy_dataset

    empty = make_toy_dataset(tmp_path / "no-val", count=5)  # indices 0-4: all train
    assert len(open_dataset(empty, "val")) == 0
    cli = [sys.executable, "-c", "from spacemesh.cli import main; main()", "export"]
    for source in (toy_model.run, toy_model.repository):
        out = tmp_path / f"models-{source.name}"
        done = subprocess.run([*cli, str(source), "--out", str(out), "--version", "9",
                               "--calibrate-data", str(empty), "--threads", "1"],
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 2, done.stderr[-2000:]
        assert done.stderr.count("\n") == 1, done.stderr
        assert "the val split has no shapes to calibrate on" in done.stderr
        assert not out.exists()
