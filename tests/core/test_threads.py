"""``--threads`` means one thing everywhere (spacemesh.threads), and idle threads sleep."""

from __future__ import annotations

import subprocess
import sys

import pytest
import typer

from spacemesh.cli import _register
from spacemesh.cli.common import app
from spacemesh.threads import default_threads, resolve_threads

_register()

#: Every command that has --threads.
COMMANDS = ("fit", "generate", "repair", "eval", "train", "export")


def test_zero_means_one_per_core_and_n_means_n():
    assert default_threads() >= 1
    assert resolve_threads(0) == resolve_threads(None) == default_threads()
    assert resolve_threads(3) == 3
    with pytest.raises(ValueError, match="threads must be"):
        resolve_threads(-1)


def test_every_command_states_the_same_threads_option():
    root = typer.main.get_command(app)
    helps = set()
    for name in COMMANDS:
        (option,) = [p for p in root.commands[name].params if "--threads" in p.opts]
        helps.add(option.help)
    assert len(helps) == 1
    assert f"0 means one per core this process may use ({default_threads()} here)" in helps.pop()


LIMIT = r"""
import os, sys
import torch
from spacemesh.threads import limit_threads
os.environ.pop("OMP_WAIT_POLICY", None)
assert limit_threads(int(sys.argv[1])) == torch.get_num_threads()
print(torch.get_num_threads(), torch.get_num_interop_threads(), os.environ["OMP_NUM_THREADS"],
      os.environ["OMP_WAIT_POLICY"])
"""


@pytest.mark.parametrize("threads", [1, 2])
def test_limit_threads_sets_torch_blas_and_a_passive_wait(threads):
    pytest.importorskip("torch")
    done = subprocess.run([sys.executable, "-c", LIMIT, str(threads)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == [str(threads), "1", str(threads), "PASSIVE"]


def test_onnxruntime_sessions_do_not_spin(tmp_path):
    onnx = pytest.importorskip("onnx")
    pytest.importorskip("onnxruntime")
    from onnx import TensorProto, helper

    from spacemesh.runtime.repository import SessionOptions, create_session

    graph = helper.make_graph(
        [helper.make_node("Relu", ["x"], ["y"])], "relu",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [2])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [2])],
    )
    path = tmp_path / "relu.onnx"
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)]), path)
    options = create_session(path, SessionOptions(intra_op_threads=2)).get_session_options()
    assert options.intra_op_num_threads == 2
    assert options.get_session_config_entry("session.intra_op.allow_spinning") == "0"
    assert options.get_session_config_entry("session.inter_op.allow_spinning") == "0"
