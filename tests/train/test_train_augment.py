"""Training on realistic conditioning clouds (TrainConfig.augment) and on a mix of
datasets: the ground truth stays clean, the default recipe is unchanged, the encoder
cache holds the augmented variants, and a run records both in its data card."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.data.augment import get_augment  # noqa: E402
from spacemesh.nn.config import get_config  # noqa: E402
from spacemesh.train.batching import collate  # noqa: E402
from spacemesh.train.encoder_cache import collate_variants  # noqa: E402
from spacemesh.train.loop import TrainOptions, load_samples, train  # noqa: E402
from spacemesh.train.toy import make_toy_dataset  # noqa: E402


def _collate(samples, seed, **options):
    return collate(samples, n_points=256, normals=True, pad_to=64,
                   rng=np.random.default_rng(seed), **options)


def test_the_none_preset_is_the_shipped_batch_and_realistic_keeps_the_clean_truth(toy_data):
    samples = load_samples(toy_data, "train", 64)[:4]
    shipped = _collate(samples, 1, scale_range=(0.75, 1.25))
    none = _collate(samples, 1, scale_range=(0.75, 1.25), augment=get_augment("none"))
    for name in ("points", "positions", "valid", "adjacency"):
        assert torch.equal(getattr(shipped, name), getattr(none, name)), name
    clean = _collate(samples, 1)
    realistic = _collate(samples, 1, augment=get_augment("realistic"))
    for name in ("positions", "valid", "adjacency"):  # the losses' targets: the clean mesh
        assert torch.equal(getattr(clean, name), getattr(realistic, name)), name
    assert realistic.points.shape == clean.points.shape
    assert realistic.points.dtype == torch.float32 and torch.isfinite(realistic.points).all()
    assert not torch.equal(realistic.points, clean.points)


def test_cache_variants_are_fixed_augmentations(toy_data):
    samples = load_samples(toy_data, "train", 64)
    options = {"n_points": 256, "normals": False, "pad_to": 64, "scale_range": (0.75, 1.25)}
    realistic = get_augment("realistic")
    keys = [(1, 0), (2, 1)]
    a = collate_variants(samples, keys, seed=3, augment=realistic, **options)
    b = collate_variants(samples, keys, seed=3, augment=realistic, **options)
    plain = collate_variants(samples, keys, seed=3, **options)
    assert torch.equal(a.points, b.points)
    assert torch.equal(a.positions, plain.positions)  # the scaling is drawn first
    assert not torch.equal(a.points, plain.points)


def test_a_realistic_mixed_run_validates_on_both_clouds_and_records_them(
        toy_model, toy_data, tmp_path):
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    other = make_toy_dataset(tmp_path / "other", count=20, seed=5)
    config = get_config("tiny-local").with_train(
        diffusion_only=True, encoder_cache=2, augment="realistic", val_every=2,
        checkpoint_every=2, val_shapes=2, batch_size=3)
    run = tmp_path / "run"
    try:
        train(TrainOptions(config=config, data=toy_model.data, out=run, steps=2,
                           progress=False, base=toy_model.repository, mix=(other,)),
              log=lambda _m: None)
    finally:
        torch.set_num_threads(before)
    row = list(csv.DictReader(open(run / "metrics.csv")))[-1]
    assert float(row["val_epsilon"]) > 0 and float(row["val_epsilon_augmented"]) > 0
    assert row["val_epsilon"] != row["val_epsilon_augmented"]
    card = json.loads((run / "data.json").read_text())
    assert card["augment"] == "realistic"
    assert card["mix"][0]["dataset"] == "other" and card["mix"][0]["train_shapes_used"] == 16
    mixed = len(load_samples(toy_model.data, "train", 64)) + 16
    assert card["train_shapes_used"] == mixed
