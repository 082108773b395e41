"""``spacemesh batch`` on a real local Ray (2 CPUs, one session for the module) with the
shipped model: one manifest row per input and an error row for a corrupt file (exit 1),
outputs byte-identical to ``spacemesh generate`` / ``spacemesh repair``, a rerun that
skips what is done, and bad usage as one line with exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from spacemesh.cli import _register
from spacemesh.cli.common import app

ray = pytest.importorskip("ray")
pytest.importorskip("fsspec")

#: Clouds of the module's batch (a corrupt PLY is added to them).
CLOUDS = 4


@pytest.fixture(scope="module")
def model_dir() -> Path:
    from spacemesh.runtime.repository import default_model_dir, resolve_version_dir

    if not default_model_dir().exists():
        pytest.skip("no shipped model in this checkout")
    return resolve_version_dir(default_model_dir())


@pytest.fixture(scope="module")
def ray_cluster():
    """One local Ray for the module (``spacemesh batch`` joins the one already started)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def _cloud(path: Path, seed: int, count: int = 300) -> Path:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(count, 3))
    np.savetxt(path, d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.5, 1.5, 3))
    return path


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("batch-in")
    for i in range(CLOUDS):
        _cloud(folder / f"cloud{i}.xyz", i)
    (folder / "sub").mkdir()
    (folder / "sub" / "corrupt.ply").write_bytes(
        b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1 2\n")
    (folder / "notes.md").write_text("not an input: folders give their point clouds only")
    return folder


def invoke(*args: str):
    _register()
    return CliRunner().invoke(app, ["batch", *args])


def _rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def first_run(ray_cluster, model_dir, inputs, tmp_path_factory):
    out = tmp_path_factory.mktemp("batch-out")
    result = invoke(str(inputs), "--out", str(out), "--workers", "2", "--model", str(model_dir))
    return result, out


def test_one_row_per_input_and_an_error_row_for_the_corrupt_file(first_run, inputs):
    result, out = first_run
    assert result.exit_code == 1, result.output
    rows = _rows(out)
    assert sorted(Path(row["input"]).name for row in rows) == sorted(
        [f"cloud{i}.xyz" for i in range(CLOUDS)] + ["corrupt.ply"])
    (bad,) = [row for row in rows if row["error_kind"]]
    assert bad["input"] == str(inputs / "sub" / "corrupt.ply")
    assert bad["error_kind"] == "malformed-input" and "PLY" in bad["error"]
    assert bad["output"] is None
    for row in rows:
        if row is bad:
            continue
        assert row["output"] == str(out / (Path(row["input"]).stem + ".obj"))
        assert Path(row["output"]).is_file() and row["faces"] > 0
        assert row["operation"] == "generate" and row["seconds"] > 0
        assert row["fit"]["n_points"] == 300 and "coverage" in row["fit"]
        assert row["points_read"] == row["points_used"] == 300
    lines = [line for line in result.stderr.splitlines() if line.startswith("[")]
    assert len(lines) == CLOUDS + 1  # one progress line per finished input
    assert f"{CLOUDS + 1} inputs: {CLOUDS} meshed, 1 failed, 0 already done" in result.stdout
    pyarrow = pytest.importorskip("pyarrow.parquet")
    table = pyarrow.read_table(out / "manifest.parquet").to_pylist()
    assert [row["input"] for row in table] == [row["input"] for row in rows]
    assert [json.loads(row["fit"]) if row["fit"] else None for row in table] == [
        row["fit"] for row in rows]


def test_outputs_are_byte_identical_to_spacemesh_generate(first_run, inputs, model_dir,
                                                          tmp_path):
    _, out = first_run
    single = tmp_path / "single.obj"
    done = CliRunner().invoke(app, ["generate", str(inputs / "cloud1.xyz"), "-o", str(single),
                                    "--model", str(model_dir), "--threads", "1",
                                    "--no-progress"])
    assert done.exit_code == 0, done.output
    assert single.read_bytes() == (out / "cloud1.obj").read_bytes()


def test_options_and_format_match_spacemesh_generate(ray_cluster, model_dir, inputs, tmp_path):
    flags = ["--seed", "5", "--start", "points", "--target-vertices", "60", "--samples", "2"]
    out = tmp_path / "out"
    result = invoke(str(inputs / "cloud2.xyz"), "--out", str(out), "--format", "ply",
                    "--model", str(model_dir), *flags)
    assert result.exit_code == 0, result.output
    (row,) = _rows(out)
    assert row["output"] == str(out / "cloud2.ply") and row["error_kind"] is None
    single = tmp_path / "single.ply"
    done = CliRunner().invoke(app, ["generate", str(inputs / "cloud2.xyz"), "-o", str(single),
                                    "--model", str(model_dir), "--threads", "1",
                                    "--no-progress", *flags])
    assert done.exit_code == 0, done.output
    assert single.read_bytes() == (out / "cloud2.ply").read_bytes()


def test_a_rerun_skips_finished_inputs(first_run, inputs, model_dir):
    _, out = first_run
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("*.obj")}
    again = invoke(str(inputs), "--out", str(out), "--model", str(model_dir))
    assert again.exit_code == 1, again.output  # the corrupt file's row is still an error
    assert f"0 meshed, 0 failed, {CLOUDS + 1} already done (0 workers" in again.stdout
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.obj")} == before
    (out / "cloud3.obj").unlink()  # a lost output is made again; the error retried on ask
    third = invoke(str(inputs), "--out", str(out), "--model", str(model_dir),
                   "--retry-errors")
    assert third.exit_code == 1, third.output
    assert f"1 meshed, 1 failed, {CLOUDS - 1} already done" in third.stdout
    assert (out / "cloud3.obj").is_file()
    rows = _rows(out)
    assert len(rows) == CLOUDS + 1 and len({row["input"] for row in rows}) == CLOUDS + 1


def test_a_list_of_inputs_and_a_glob(ray_cluster, model_dir, inputs, tmp_path):
    listing = inputs.parent / "inputs.txt"  # a relative entry: from the list's folder
    listing.write_text(f"# two clouds\n{inputs / 'cloud0.xyz'}\n\n"
                       f"{Path(inputs.name) / 'cloud1.xyz'}\n")
    out = tmp_path / "out"
    result = invoke(f"@{listing}", str(inputs / "cloud*.xyz"), "--out", str(out),
                    "--workers", "1", "--model", str(model_dir), "--no-progress")
    assert result.exit_code == 0, result.output
    assert sorted(Path(row["input"]).name for row in _rows(out)) == [
        f"cloud{i}.xyz" for i in range(CLOUDS)]
    assert not [line for line in result.stderr.splitlines() if line.startswith("[")]


def test_repair_holes_matches_spacemesh_repair(ray_cluster, model_dir, tmp_path):
    from spacemesh.examples import icosphere
    from spacemesh.io import load_mesh, save_mesh
    from spacemesh.topology import check_topology
    from tests.repair.auto_meshes import punched

    source = tmp_path / "holed.obj"
    save_mesh(punched(icosphere(3), [[0.0, 0.0, 1.0]]), source)
    out = tmp_path / "out"
    result = invoke(str(source), "--out", str(out), "--repair", "holes", "--model",
                    str(model_dir))
    assert result.exit_code == 0, result.output
    (row,) = _rows(out)
    assert row["operation"] == "repair" and row["repair"]["auto_region"]
    assert check_topology(load_mesh(out / "holed.obj")).is_closed_oriented_manifold
    single = tmp_path / "single.obj"
    done = CliRunner().invoke(app, ["repair", str(source), "-o", str(single), "--holes",
                                    "--model", str(model_dir), "--threads", "1",
                                    "--no-progress"])
    assert done.exit_code == 0, done.output
    assert single.read_bytes() == (out / "holed.obj").read_bytes()


@pytest.mark.parametrize(("flags", "message"), [
    (["--seed", "1e3"], "--seed: seed must be an integer"),
    (["--samples", "0"], "--samples: samples must be in 1..16, not 0"),
    (["--format", "stl"], "--format: expected one of obj, ply, off, glb, gltf"),
    (["--repair", "everything"], "--repair: expected one of auto, holes, defects"),
    (["--repair", "holes", "--target-vertices", "60"], "--target-vertices: does not apply"),
])
def test_bad_usage_is_one_line_and_exit_2(model_dir, inputs, tmp_path, flags, message):
    result = invoke(str(inputs), "--out", str(tmp_path / "out"), "--model", str(model_dir),
                    *flags)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("spacemesh: error: "), result.stderr
    assert message in lines[0]
    assert not (tmp_path / "out").exists()


def test_missing_inputs_and_other_settings_are_bad_usage(first_run, inputs, model_dir,
                                                         tmp_path):
    missing = invoke(str(tmp_path / "nothing-here"), "--out", str(tmp_path / "o"),
                     "--model", str(model_dir))
    assert missing.exit_code == 2 and "no such file or folder" in missing.stderr
    empty = invoke(str(tmp_path / "*.ply"), "--out", str(tmp_path / "o"), "--model",
                   str(model_dir))
    assert empty.exit_code == 2 and "matches no file" in empty.stderr
    _, out = first_run
    other = invoke(str(inputs), "--out", str(out), "--model", str(model_dir), "--seed", "7")
    assert other.exit_code == 2, other.output
    lines = other.stderr.strip().splitlines()
    assert len(lines) == 1 and "other settings (options)" in lines[0]


def test_names_of_inputs_are_unique_and_stable(tmp_path):
    from spacemesh.batch.inputs import expand_inputs

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for folder in ("a", "b"):
        _cloud(tmp_path / folder / "scan.xyz", 0, 20)
    _cloud(tmp_path / "a" / "other.xyz", 1, 20)
    items = expand_inputs([str(tmp_path / "a" / "*.xyz"), str(tmp_path / "b" / "scan.xyz"),
                           str(tmp_path / "a" / "other.xyz")])
    names = [item.name for item in items]
    assert len(items) == 3 and len(set(names)) == 3  # other.xyz named twice, meshed once
    assert "other" in names and sum(name.startswith("scan-") for name in names) == 2
    nested = expand_inputs([str(tmp_path)])
    assert sorted(item.name for item in nested) == ["a/other", "a/scan", "b/scan"]


def test_inputs_at_an_fsspec_url():
    import fsspec

    from spacemesh.batch.inputs import expand_inputs

    fs = fsspec.filesystem("memory")
    fs.pipe("/batch-test/clouds/one.xyz", b"0 0 0\n")
    fs.pipe("/batch-test/clouds/two.ply", b"ply\n")
    fs.pipe("/batch-test/list.txt", b"clouds/one.xyz\nmemory://batch-test/clouds/two.ply\n")
    listed = expand_inputs(["@memory://batch-test/list.txt"])
    assert [(i.source, i.name) for i in listed] == [
        ("memory:///batch-test/clouds/one.xyz", "one"),
        ("memory:///batch-test/clouds/two.ply", "two")]
    assert [i.name for i in expand_inputs(["memory://batch-test/clouds"], repair=True)] == [
        "two"]


def _binary_ply(path: Path, points: np.ndarray) -> Path:
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n")
    path.write_bytes(header.encode() + points.astype("<f4").tobytes())
    return path


def test_a_million_point_binary_ply_is_reduced_and_matches_spacemesh_generate(
        ray_cluster, model_dir, tmp_path):
    """Batch reads as ``spacemesh generate`` does (one path): a 1,000,000-point cloud is
    reduced to the working size, not refused, and gives the command's bytes."""
    rng = np.random.default_rng(11)
    d = rng.normal(size=(1_000_000, 3))
    big = _binary_ply(tmp_path / "million.ply",
                      d / np.linalg.norm(d, axis=1, keepdims=True) * [1.0, 0.7, 0.5])
    out = tmp_path / "out"
    result = invoke(str(big), "--out", str(out), "--model", str(model_dir))
    assert result.exit_code == 0, result.output
    (row,) = _rows(out)
    assert row["error_kind"] is None and row["faces"] > 0, row
    assert row["points_read"] == 1_000_000
    assert row["points_used"] == 200_000  # the working size, as the command reduces
    single = tmp_path / "single.obj"
    done = CliRunner().invoke(app, ["generate", str(big), "-o", str(single),
                                    "--model", str(model_dir), "--no-progress"])
    assert done.exit_code == 0, done.output
    assert single.read_bytes() == (out / "million.obj").read_bytes()
