"""Fitting is torch-side: the numpy core, its metrics and the runtime import neither it
nor torch."""

from __future__ import annotations

import subprocess
import sys

from tests.factories import BLOCK_TORCH

SCRIPT = BLOCK_TORCH + r"""
import spacemesh.decode, spacemesh.encode, spacemesh.metrics.connectivity, spacemesh.runtime
from spacemesh.examples import icosphere
from spacemesh.encode import encode_connectivity
from spacemesh.metrics.connectivity import next_accuracy

truth = encode_connectivity(icosphere(1))
assert next_accuracy(truth, truth) == 1.0
assert "torch" not in sys.modules and "spacemesh.fitting" not in sys.modules
try:
    import spacemesh.fitting
except ImportError as error:
    print("blocked", error)
"""


def test_core_and_runtime_import_without_fitting_or_torch():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.startswith("blocked torch is blocked")
