"""The runtime never imports torch: a subprocess blocks it and still generates a mesh."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.factories import BLOCK_TORCH

SCRIPT = BLOCK_TORCH + r"""
import numpy as np

import spacemesh.runtime
from spacemesh.runtime import MeshGenerator

generator = MeshGenerator.from_repository(sys.argv[1], threads=1)
points = np.random.default_rng(0).normal(size=(300, 3))
result = generator.generate(points, seed=1, steps=3)
assert "torch" not in sys.modules
print("ok", result.mesh.n_vertices, result.mesh.n_faces)
"""


def test_runtime_generates_without_torch(toy_model):
    pytest.importorskip("onnxruntime")
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(toy_model.repository)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith("ok")
