"""The golden check at start-up: a model whose graphs no longer give the outputs its
manifest recorded is refused by the runtime, the server and ``spacemesh generate``."""

from __future__ import annotations

import json
import logging
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from spacemesh.runtime.golden import SECTION, TOLERANCE, golden_mismatches
from spacemesh.runtime.repository import MANIFEST, ModelRepository, ModelRepositoryError

SHIPPED = Path(__file__).resolve().parents[2] / "models" / "spacemesh-small"
CLI = "from spacemesh.cli import main; main()"


def _golden_copy(source: Path, folder: Path) -> Path:
    """A copy of a model version with its golden section recorded now."""
    from spacemesh.export.golden import record_golden

    copy = folder / "model" / "1"
    shutil.copytree(source, copy)
    record_golden(copy)
    return copy


def _edit_weight(version: Path, graph: str, change: float = 0.1) -> str:
    """Add noise of ``change`` times its spread to ``graph``'s largest float initializer
    (neither a scale nor a shift, which a normalisation after it could undo) and write the
    file's new sha256 and size into the manifest, as a careless re-export would."""
    import onnx
    from onnx import numpy_helper

    from spacemesh.runtime.repository import sha256_file

    path = version / f"{graph}.onnx"
    model = onnx.load(path)
    weights = [t for t in model.graph.initializer if t.data_type == onnx.TensorProto.FLOAT]
    weight = max(weights, key=lambda t: int(np.prod(t.dims)))
    values = numpy_helper.to_array(weight)
    noise = np.random.default_rng(0).standard_normal(values.shape) * change * values.std()
    values = (values + noise).astype(np.float32)
    weight.CopyFrom(numpy_helper.from_array(values, weight.name))
    onnx.save(model, path)
    manifest = json.loads((version / MANIFEST).read_text())
    manifest["files"][path.name] = {"sha256": sha256_file(path), "bytes": path.stat().st_size}
    (version / MANIFEST).write_text(json.dumps(manifest))
    return weight.name


@pytest.mark.parametrize("version", [1, 7])
def test_shipped_versions_pass_with_1_and_2_threads(version):
    path = SHIPPED / str(version)
    manifest = json.loads((path / MANIFEST).read_text())
    section = manifest[SECTION]
    assert set(section["graphs"]) == {"encoder", "denoiser", "connectivity"}
    assert section["tolerance"] == TOLERANCE
    for threads in (1, 2):
        repository = ModelRepository.load(path, threads=threads)  # checks it
        # and far inside the tolerance: a tenth of it is never approached
        strict = {**repository.manifest, SECTION: {**section, "tolerance": TOLERANCE / 10}}
        assert golden_mismatches(repository.backend, strict) == []


@pytest.mark.parametrize("graph", ["encoder", "denoiser", "connectivity"])
def test_a_changed_weight_is_refused_naming_its_graph(toy_repository, tmp_path, graph):
    version = _golden_copy(toy_repository, tmp_path)
    ModelRepository.load(version)  # passes before the edit
    _edit_weight(version, graph)
    with pytest.raises(ModelRepositoryError, match="fails its golden check") as caught:
        ModelRepository.load(version)
    message = str(caught.value)
    assert f"{graph} graph output" in message, message
    assert re.search(r"moved by [0-9.e+-]+ of its rms", message), message
    if graph != "encoder":  # the encoder's volumes feed the other two; these stand alone
        assert all(f"{graph} graph output" in part for part in message.split("; ")
                   if "graph output" in part), message


def test_the_server_never_becomes_ready_and_says_why(toy_repository, tmp_path, start_server):
    version = _golden_copy(toy_repository, tmp_path)
    _edit_weight(version, "connectivity")
    with pytest.raises(RuntimeError, match="the model did not become ready") as caught:
        start_server(model=version)
    assert "golden check" in str(caught.value)
    assert "connectivity graph output" in str(caught.value)


def test_spacemesh_serve_and_generate_refuse_it(toy_repository, tmp_path):
    version = _golden_copy(toy_repository, tmp_path)
    _edit_weight(version, "denoiser")
    served = subprocess.run(
        [sys.executable, "-c", CLI, "serve", "--model", str(version), "--port", "0",
         "--grpc-port", "0", "--host", "127.0.0.1", "--ort-threads", "1"],
        capture_output=True, text=True, timeout=120)
    assert served.returncode == 1, served.stderr
    assert "cannot load the model" in served.stderr
    assert "denoiser graph output 'eps'" in served.stderr
    points = tmp_path / "points.xyz"
    rng = np.random.default_rng(0)
    np.savetxt(points, rng.standard_normal((200, 3)))
    generated = subprocess.run(
        [sys.executable, "-c", CLI, "generate", str(points), "--model", str(version),
         "--output", str(tmp_path / "mesh.obj"), "--threads", "1", "--no-progress"],
        capture_output=True, text=True, timeout=120)
    assert generated.returncode == 2, generated.stderr
    lines = generated.stderr.strip().splitlines()
    assert len(lines) == 1 and "denoiser graph output 'eps'" in lines[0], generated.stderr
    assert not (tmp_path / "mesh.obj").exists()


def test_a_manifest_without_the_section_loads_with_a_warning(toy_repository, tmp_path,
                                                              caplog):
    copy = tmp_path / "old" / "1"
    shutil.copytree(toy_repository, copy)
    manifest = json.loads((copy / MANIFEST).read_text())
    manifest.pop(SECTION, None)  # exported before golden checks existed
    (copy / MANIFEST).write_text(json.dumps(manifest))
    with caplog.at_level(logging.WARNING, logger="spacemesh.runtime.repository"):
        repository = ModelRepository.load(copy)
    assert repository.path == copy
    assert any("no golden section" in r.getMessage() for r in caplog.records), caplog.text


def test_recording_changes_nothing_but_the_section(toy_repository, tmp_path):
    from spacemesh.export.golden import main

    copy = tmp_path / "model" / "1"
    shutil.copytree(toy_repository, copy)
    before = json.loads((copy / MANIFEST).read_text())
    graphs = {f: (copy / f).read_bytes() for f in before["files"]}
    assert main([str(copy)]) == 0
    after = json.loads((copy / MANIFEST).read_text())
    assert {k: v for k, v in after.items() if k != SECTION} == {
        k: v for k, v in before.items() if k != SECTION}
    assert {f: (copy / f).read_bytes() for f in before["files"]} == graphs
    assert main([str(tmp_path / "nothing")]) == 2
