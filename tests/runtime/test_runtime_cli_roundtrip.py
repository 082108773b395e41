"""Train, export (the session fixture does both through the CLI) and generate via the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from spacemesh.io import load_mesh
from spacemesh.topology import check_topology

CLI = [sys.executable, "-c", "from spacemesh.cli import main; main()"]


def test_train_export_generate_round_trip(toy_model, tmp_path):
    points = tmp_path / "cloud.xyz"
    d = np.random.default_rng(1).normal(size=(256, 3))
    np.savetxt(points, 5.0 * d / np.linalg.norm(d, axis=1, keepdims=True) + 1.0)
    out = tmp_path / "mesh.obj"
    done = subprocess.run(
        [*CLI, "generate", str(points), "-o", str(out), "--model", str(toy_model.repository),
         "--seed", "4", "--steps", "4", "--threads", "1", "--json"],
        capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout)
    assert summary["steps"] == 4 and summary["model"] == "spacemesh-tiny"
    assert out.is_file()
    if summary["faces"]:  # an untrained toy model may decode to the empty mesh
        mesh = load_mesh(out)
        assert mesh.n_faces == summary["faces"]
        assert check_topology(mesh).is_closed_oriented_manifold


def test_generate_reports_user_errors(toy_model, tmp_path):
    done = subprocess.run([*CLI, "generate", str(tmp_path / "missing.xyz"), "-o",
                           str(tmp_path / "m.obj"), "--model", str(toy_model.repository)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "no such file" in done.stderr
    cloud = tmp_path / "c.xyz"
    np.savetxt(cloud, np.random.default_rng(0).normal(size=(20, 3)))
    done = subprocess.run([*CLI, "generate", str(cloud), "-o", str(tmp_path / "m.obj"),
                           "--model", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "manifest.json" in done.stderr
    pytest.importorskip("onnxruntime")
