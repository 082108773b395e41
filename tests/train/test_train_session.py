"""The bounded training session behind scripts/gpu_train.sh: it refuses to start, with
one line per problem and exit status 2, when anything it needs is missing."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from spacemesh.export import session

ROOT = Path(__file__).resolve().parents[2]


def test_missing_data_base_and_budget_are_refused_before_training(tmp_path, capsys):
    status = session.main(["--data", str(tmp_path / "none"), "--out", str(tmp_path / "out"),
                           "--base", str(tmp_path / "nobase"), "--minutes", "1"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(lines) == 3
    assert all(line.startswith("gpu_train: cannot start: ") for line in lines)
    assert "--data" in lines[0] and "--base" in lines[1] and "--minutes 1" in lines[2]
    assert not (tmp_path / "out" / "summary.json").exists()


def test_a_missing_mix_and_an_unknown_augmentation_are_refused(tmp_path, capsys):
    status = session.main(["--data", str(tmp_path / "none"), "--out", str(tmp_path / "out"),
                           "--mix", str(tmp_path / "other"), "--augment", "wild"])
    err = capsys.readouterr().err
    assert status == 2 and f"--mix {tmp_path / 'other'}: no dataset there" in err
    assert "--augment wild: choose from none, realistic" in err


def test_missing_modules_and_checkpoint_are_named(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(session, "REQUIRED_MODULES", ("numpy", "no_such_module_22"))
    status = session.main(["--data", str(tmp_path), "--out", str(tmp_path / "out"),
                           "--resume", "--run", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert status == 2 and "missing Python modules: no_such_module_22" in err
    assert "--resume: no checkpoint" in err


def test_the_script_needs_out_and_passes_problems_through(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "OUT"}
    done = subprocess.run(["bash", "scripts/gpu_train.sh", "--data", "x"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.strip() == (
        "gpu_train: cannot start: set OUT to the folder the results go to")
    env.update(OUT=str(tmp_path / "out"), PYTHON=os.environ.get("PYTHON", _python()))
    done = subprocess.run(["bash", "scripts/gpu_train.sh", "--data", str(tmp_path / "none")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "--data" in done.stderr and "Traceback" not in done.stderr


def _python() -> str:
    import sys

    return sys.executable
