"""The training loop: logs, checkpoints, exact resume, and DDP on CPU (gloo)."""

from __future__ import annotations

import csv
import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.config import get_config  # noqa: E402
from spacemesh.train.checkpoint import latest_checkpoint, load_checkpoint  # noqa: E402
from spacemesh.train.loop import TrainOptions, train  # noqa: E402


def _config():
    return get_config("tiny").with_train(val_every=2, checkpoint_every=2, val_shapes=2,
                                         batch_size=3)


def test_training_writes_logs_curves_and_checkpoints(toy_data, tmp_path, one_thread):
    run = tmp_path / "run"
    summary = train(TrainOptions(config=_config(), data=toy_data, out=run, steps=2,
                                 progress=False), log=lambda m: None)
    assert summary.steps == 2 and summary.checkpoint == latest_checkpoint(run)
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    assert rows and {"train_epsilon", "train_edge", "val_edge_f1"} <= set(rows[-1])
    assert (run / "curves.png").stat().st_size > 0
    state = load_checkpoint(summary.checkpoint)
    assert state["step"] == 2 and state["config"].name == "tiny"
    assert state["extra"]["data"]["train_shapes_used"] > 0
    assert (run / "checkpoints" / "step-0000002.pt").is_file()


def test_resume_continues_exactly(toy_data, tmp_path, one_thread):
    straight = tmp_path / "straight"
    train(TrainOptions(config=_config(), data=toy_data, out=straight, steps=4, progress=False),
          log=lambda m: None)
    split = tmp_path / "split"
    train(TrainOptions(config=_config(), data=toy_data, out=split, steps=2, progress=False),
          log=lambda m: None)
    summary = train(TrainOptions(config=_config(), data=toy_data, out=split, steps=4,
                                 resume=True, progress=False), log=lambda m: None)
    assert summary.steps == 4
    a = load_checkpoint(latest_checkpoint(straight))["model"]
    b = load_checkpoint(latest_checkpoint(split))["model"]
    for key in a:
        assert torch.equal(a[key], b[key]), key
    steps = [float(r["step"]) for r in csv.DictReader(open(split / "metrics.csv"))]
    assert steps == sorted(set(steps))


def test_resume_takes_the_requested_jitter(toy_data, tmp_path, one_thread):
    run = tmp_path / "run"
    train(TrainOptions(config=_config(), data=toy_data, out=run, steps=2, progress=False),
          log=lambda m: None)
    noisy = _config().with_train(connectivity_jitter=0.03)
    summary = train(TrainOptions(config=noisy, data=toy_data, out=run, steps=3, resume=True,
                                 progress=False), log=lambda m: None)
    state = load_checkpoint(summary.checkpoint)
    assert state["step"] == 3 and state["config"].train.connectivity_jitter == 0.03
    assert json.loads((run / "config.json").read_text())["train"]["connectivity_jitter"] == 0.03


def test_ddp_on_cpu_with_two_processes(toy_data, tmp_path):
    """``torchrun`` with two gloo processes runs the real ``spacemesh train`` command."""
    script = Path(sys.executable).with_name("spacemesh")
    if not script.is_file():
        pytest.skip("the spacemesh console script is not installed beside this python")
    run = tmp_path / "ddp"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    command = [
        sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2",
        "--master_port", str(29500 + os.getpid() % 1000), str(script), "train",
        "--config", "tiny", "--data", str(toy_data), "--out", str(run), "--steps", "2",
        "--device", "cpu", "--threads", "1", "--no-progress",
    ]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    state = load_checkpoint(latest_checkpoint(run))
    assert state["step"] == 2 and state["extra"]["world_size"] == 2


def test_learning_rate_warms_up_then_decays_to_the_final_ratio():
    from spacemesh.nn.config import TrainConfig
    from spacemesh.train.loop import learning_rate

    train = TrainConfig(lr=1e-3, warmup=10, steps=100, final_lr_ratio=0.1)
    rates = [learning_rate(train, step) for step in range(101)]
    assert rates[0] == pytest.approx(1e-4)  # 1/10 of the way through the warm-up
    assert max(rates) <= 1e-3
    assert all(a >= b for a, b in itertools.pairwise(rates[10:]))  # decays
    assert rates[100] == pytest.approx(1e-4)
    constant = TrainConfig(lr=1e-3, warmup=1, steps=100)  # final_lr_ratio 1: no decay
    assert {learning_rate(constant, s) for s in (0, 50, 100)} == {1e-3}
