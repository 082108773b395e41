"""Fine-tuning (``spacemesh train --init-from RUN``): a run that starts from another's
weights, with a new optimiser and schedule."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnxruntime")

from spacemesh.nn.config import get_config  # noqa: E402
from spacemesh.train.checkpoint import latest_checkpoint, load_checkpoint  # noqa: E402
from spacemesh.train.distributed import setup_distributed  # noqa: E402
from spacemesh.train.loop import Trainer, TrainOptions, train  # noqa: E402
from tests.export.conftest import invoke_train, tiny_config  # noqa: E402


def _quiet(message: str) -> None:
    pass


def _same_weights(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_a_fine_tune_starts_from_the_weights_and_inherits_the_base(toy_model, base_run,
                                                                   tmp_path):
    base, run = base_run
    source = load_checkpoint(latest_checkpoint(run))
    options = TrainOptions(config=tiny_config(), data=toy_model.data, out=tmp_path / "tune",
                           steps=2, progress=False, init_from=run, threads=1)
    trainer = Trainer(options, setup_distributed("cpu"), _quiet)
    assert _same_weights(trainer.model.state_dict(), source["model"])
    assert trainer.start_step == 0 and not trainer.optimizer.state
    assert trainer.base is not None and trainer.base.path == base.resolve()
    assert trainer.card["init"]["step"] == source["step"]
    assert trainer.card["init"]["data"]["dataset"] == source["extra"]["data"]["dataset"]

    summary = trainer.run()
    state = load_checkpoint(summary.checkpoint)
    assert state["step"] == 2
    assert state["extra"]["base"]["files"] == source["extra"]["base"]["files"]
    assert not _same_weights(state["model"], source["model"])  # it trained
    # resuming the fine-tune keeps its record of where it started
    resumed = train(TrainOptions(config=tiny_config(), data=toy_model.data,
                                 out=tmp_path / "tune", steps=3, resume=True, progress=False,
                                 init_from=run), log=_quiet)
    assert load_checkpoint(resumed.checkpoint)["extra"]["data"]["init"] == trainer.card["init"]


def test_a_full_run_fine_tunes_without_a_base(toy_model, tmp_path):
    source = load_checkpoint(latest_checkpoint(toy_model.run))
    options = TrainOptions(config=tiny_config(), data=toy_model.data, out=tmp_path / "tune",
                           steps=1, progress=False, init_from=toy_model.run, threads=1)
    trainer = Trainer(options, setup_distributed("cpu"), _quiet)
    assert trainer.base is None
    assert _same_weights(trainer.model.state_dict(), source["model"])


def test_other_networks_or_bases_are_refused(toy_model, base_run, tmp_path):
    base, run = base_run
    small = get_config("small").with_train(val_shapes=2)
    with pytest.raises(ValueError, match="connectivity differ"):
        train(TrainOptions(config=small, data=toy_model.data, out=tmp_path / "a", steps=1,
                           progress=False, init_from=run), log=_quiet)
    with pytest.raises(ValueError, match="full run"):
        train(TrainOptions(config=tiny_config(), data=toy_model.data, out=tmp_path / "b",
                           steps=1, progress=False, init_from=toy_model.run, base=base),
              log=_quiet)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_cli_refuses_a_missing_init_in_one_line(toy_model, tmp_path):
    result = invoke_train(toy_model, tmp_path / "run", "--init-from", str(tmp_path / "nowhere"))
    assert result.exit_code != 0
    assert "nowhere" in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


@pytest.mark.parametrize(("extra", "message"), [
    (["--lr", "0"], "--lr must be positive"),
    (["--lr", "1e-4", "--resume"], "--lr applies to new runs"),
    (["--false-positive-weight", "1", "--resume"], "--false-positive-weight applies to new"),
])
def test_cli_refuses_a_bad_learning_rate_in_one_line(toy_model, tmp_path, extra, message):
    result = invoke_train(toy_model, tmp_path / "run", *extra)
    assert result.exit_code != 0
    assert message in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


def test_the_cli_learning_rate_reaches_the_run(toy_model, tmp_path):
    run = tmp_path / "run"
    result = invoke_train(toy_model, run, "--steps", "1", "--lr", "2.5e-4", "--threads", "1",
                          "--no-progress")
    assert result.exit_code == 0, result.output
    assert load_checkpoint(latest_checkpoint(run))["config"].train.lr == 2.5e-4


def test_the_cli_false_positive_weight_reaches_the_run_and_its_loss(toy_model, tmp_path):
    import torch

    from spacemesh.nn.model import pairwise_edge_loss

    run = tmp_path / "run"
    result = invoke_train(toy_model, run, "--steps", "1", "--false-positive-weight", "2.0",
                          "--threads", "1", "--no-progress")
    assert result.exit_code == 0, result.output
    config = load_checkpoint(latest_checkpoint(run))["config"]
    assert config.train.false_positive_weight == 2.0
    # hard negatives (a non-edge below tau) weigh more than the paper's lambda
    x = torch.zeros(1, 4, config.connectivity.adjacency_dim)
    x[0, :, 0] = torch.tensor([0.0, 0.1, 0.2, 3.0])  # a space coordinate
    adjacency = torch.zeros(1, 4, 4, dtype=torch.bool)
    adjacency[0, 0, 1] = adjacency[0, 1, 0] = adjacency[0, 1, 2] = adjacency[0, 2, 1] = True
    valid = torch.ones(1, 4, dtype=torch.bool)
    tau = torch.ones(1)
    paper = pairwise_edge_loss(x, tau, adjacency, valid,
                               config.with_train(false_positive_weight=None))
    hard = pairwise_edge_loss(x, tau, adjacency, valid, config)
    assert float(hard) > float(paper) > 0.0


def test_a_fine_tune_starts_from_an_exported_connectivity_only_model(toy_model, base_run,
                                                                     exported_base_run,
                                                                     tmp_path):
    import json
    import shutil

    from spacemesh.train.onnx_import import init_from_repository

    base, run = base_run
    root = base.parent.parent  # the base's repository root: the model is next to it
    exported = exported_base_run
    source = load_checkpoint(latest_checkpoint(run))
    init = init_from_repository(exported)
    # the weights read back from the graph are the run's own
    for key, value in init["connectivity"].items():
        assert torch.allclose(value, source["model"][f"connectivity.{key}"], atol=1e-6), key
    assert init["extra"]["base"]["files"] == source["extra"]["base"]["files"]

    options = TrainOptions(config=tiny_config(), data=toy_model.data, out=tmp_path / "tune",
                           steps=2, progress=False, init_from=exported, threads=1)
    trainer = Trainer(options, setup_distributed("cpu"), _quiet)
    ours = {k: v for k, v in trainer.model.connectivity.state_dict().items()}
    assert _same_weights(ours, init["connectivity"])
    assert trainer.base is not None and trainer.base.path == base.resolve()
    assert trainer.card["init"]["checkpoint"] == str(exported)
    summary = trainer.run()
    assert load_checkpoint(summary.checkpoint)["step"] == 2

    # a full model cannot be fine-tuned from its repository; a changed graph is refused
    with pytest.raises(ValueError, match="connectivity-only"):
        init_from_repository(base)
    broken = root / "spacemesh-tiny-conn" / "2"
    shutil.copytree(exported, broken)
    manifest = json.loads((broken / "manifest.json").read_text())
    manifest["training"]["base"]["files"]["encoder.onnx"] = "0" * 64
    (broken / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match="changed since training"):
        init_from_repository(broken)
