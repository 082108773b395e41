"""Diffusion-only runs: the frozen encoder's cache, the local-point denoiser end to end
(train, export, onnxruntime generate), exact resume, and stopping on a signal."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from spacemesh.nn.config import get_config  # noqa: E402
from spacemesh.nn.model import model_from_config  # noqa: E402
from spacemesh.train.checkpoint import latest_checkpoint, load_checkpoint  # noqa: E402
from spacemesh.train.encoder_cache import EncoderCache, collate_variants  # noqa: E402
from spacemesh.train.loop import StopRequests, TrainOptions, load_samples, train  # noqa: E402


def _quiet(_message: str) -> None:
    pass


def _config(name: str = "tiny", **changes):
    return get_config(name).with_train(val_every=2, checkpoint_every=2, val_shapes=2,
                                       batch_size=3, **changes)


@pytest.fixture(scope="module")
def full_run(toy_data, tmp_path_factory):
    """A 2-step joint run of ``tiny``: the trained encoder the diffusion-only runs freeze."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        run = tmp_path_factory.mktemp("full") / "run"
        train(TrainOptions(config=_config(), data=toy_data, out=run, steps=2, progress=False),
              log=_quiet)
    finally:
        torch.set_num_threads(before)
    return run


def test_the_cache_computes_each_variant_once_and_gives_the_same_batch(toy_data, one_thread):
    samples = load_samples(toy_data, "train", 64)
    calls = []
    model = model_from_config("tiny").encoder.eval()

    def counted(points):
        calls.append(len(points))
        return model(points)

    options = {"n_points": 256, "normals": False, "pad_to": 64, "scale_range": (0.75, 1.25)}
    cache = EncoderCache(counted, samples, variants=2, seed=3, device=torch.device("cpu"),
                         **options)
    rng = np.random.default_rng(0)
    batch, volumes = cache.batch([0, 1, 0, 1, 2], rng)
    assert sum(calls) == cache.misses == len(cache) <= 5
    with torch.no_grad():
        direct = model(batch.points)
    for got, want in zip(volumes, direct, strict=True):
        assert torch.allclose(got, want, atol=1e-2 * float(want.abs().max()))
    for _ in range(20):  # 3 shapes x 2 variants at most, whatever is drawn
        cache.batch([0, 1, 2], rng)
    assert cache.misses == len(cache) <= 6 and sum(calls) == cache.misses
    again = collate_variants(samples, [(1, 0)], seed=3, **options)
    twice = collate_variants(samples, [(1, 0)], seed=3, **options)
    assert torch.equal(again.points, twice.points)
    assert torch.equal(again.positions, twice.positions)
    other = collate_variants(samples, [(1, 1)], seed=3, **options)
    assert not torch.equal(again.points, other.points)


def test_diffusion_only_needs_a_trained_encoder(toy_data, tmp_path, one_thread):
    with pytest.raises(ValueError, match=r"\(--base\).*\(--init-from\)"):
        train(TrainOptions(config=_config(diffusion_only=True), data=toy_data,
                           out=tmp_path / "run", steps=1, progress=False), log=_quiet)


def test_local_denoiser_trains_alone_on_a_frozen_encoder(full_run, toy_data, tmp_path,
                                                         one_thread):
    run = tmp_path / "local"
    train(TrainOptions(config=_config("tiny-local", diffusion_only=True), data=toy_data,
                       out=run, steps=3, progress=False, init_from=full_run), log=_quiet)
    before = load_checkpoint(latest_checkpoint(full_run))["model"]
    after = load_checkpoint(latest_checkpoint(run))
    assert after["config"].denoiser.local_points == 8 and after["config"].train.diffusion_only
    for key, value in before.items():  # the encoder and connectivity are frozen
        if not key.startswith("denoiser."):
            assert torch.equal(after["model"][key], value), key
    assert any(k.startswith("denoiser.local_attention.") for k in after["model"])
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    assert rows[-1]["train_epsilon"] and rows[-1]["val_epsilon"]
    assert "train_edge" not in rows[-1] and float(rows[-1]["shapes"]) == 9


def test_local_denoiser_on_a_base_exports_and_generates(local_model, one_thread):
    """On a base model (the ``local_model`` fixture: 2 diffusion-only steps of
    ``tiny-local``, exported): only the denoiser graph is exported (the lookup of the
    nearest points inside it), the base's encoder and connectivity graphs are kept, and
    the onnxruntime pipeline generates a valid mesh with it."""
    from spacemesh.export.repository import load_trained_model
    from spacemesh.nn.model import TorchBackend
    from spacemesh.runtime.pipeline import MeshGenerator
    from spacemesh.runtime.repository import ModelRepository
    from spacemesh.topology import check_topology

    base, run, directory = local_model.base, local_model.run, local_model.directory
    assert list(csv.DictReader(open(run / "metrics.csv")))[-1]["val_epsilon"]
    for graph in ("encoder.onnx", "connectivity.onnx"):
        assert (directory / graph).read_bytes() == (base / graph).read_bytes()
    repo = ModelRepository.load(directory, threads=1)
    assert repo.manifest["graphs"]["denoiser"]["inputs"][-1] == "points"
    assert repo.manifest["training"]["connectivity_steps"] == 0
    assert repo.manifest["training"]["base"]["name"] == "spacemesh-tiny"
    model, _ = load_trained_model(run)
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 1, (2, 300, 3)).astype(np.float32)
    volumes = repo.backend.encode(points)
    x_t = rng.normal(size=(2, 70, 4)).astype(np.float32)
    t = np.array([1, 50])
    torch_eps = TorchBackend(model).denoise(x_t, t, volumes, points)
    assert np.allclose(repo.backend.denoise(x_t, t, volumes, points), torch_eps, atol=1e-4)
    embeddings = TorchBackend(model).connect(x_t[..., :3], x_t[..., 3] > 0, volumes)
    assert np.allclose(embeddings.x, repo.backend.connect(x_t[..., :3], x_t[..., 3] > 0,
                                                          volumes).x, atol=1e-4)

    generator = MeshGenerator.from_repository(directory, threads=1)
    assert generator.spec.local_points == 8
    steps = []
    result = generator.generate(rng.normal(size=(400, 3)), seed=0, start="points",
                                start_time=0.5, progress=lambda done, total: steps.append(done))
    assert steps and check_topology(result.mesh).is_closed_oriented_manifold


def test_cached_diffusion_only_run_resumes_exactly(full_run, toy_data, tmp_path, one_thread):
    config = _config("tiny-local", diffusion_only=True, encoder_cache=2)
    straight, split = tmp_path / "straight", tmp_path / "split"
    train(TrainOptions(config=config, data=toy_data, out=straight, steps=4, progress=False,
                       init_from=full_run), log=_quiet)
    train(TrainOptions(config=config, data=toy_data, out=split, steps=2, progress=False,
                       init_from=full_run), log=_quiet)
    summary = train(TrainOptions(config=config, data=toy_data, out=split, steps=4, resume=True,
                                 progress=False), log=_quiet)
    assert summary.steps == 4
    a = load_checkpoint(latest_checkpoint(straight))["model"]
    b = load_checkpoint(latest_checkpoint(split))["model"]
    for key in a:
        assert torch.equal(a[key], b[key]), key


def test_a_stop_signal_ends_the_step_with_a_checkpoint(full_run, toy_data, tmp_path,
                                                       one_thread):
    previous = signal.getsignal(signal.SIGTERM)
    run = tmp_path / "run"

    def log(message: str) -> None:  # a scheduler's SIGTERM arrives during step 2
        if message.startswith("step 1:"):
            os.kill(os.getpid(), signal.SIGTERM)

    config = _config("tiny-local", diffusion_only=True).with_train(val_every=1)
    summary = train(TrainOptions(config=config, data=toy_data, out=run, steps=50,
                                 progress=False, init_from=full_run), log=log)
    assert summary.steps == 2 and load_checkpoint(summary.checkpoint)["step"] == 2
    assert signal.getsignal(signal.SIGTERM) == previous
    resumed = train(TrainOptions(config=config, data=toy_data, out=run, steps=3, resume=True,
                                 progress=False), log=_quiet)
    assert resumed.steps == 3
    steps = [float(r["step"]) for r in csv.DictReader(open(run / "metrics.csv"))]
    assert steps == [1.0, 2.0, 3.0]
    assert json.loads((run / "config.json").read_text())["train"]["diffusion_only"]


def test_stop_requests_restore_the_handlers():
    previous = signal.getsignal(signal.SIGINT)
    with StopRequests() as stops:
        assert not stops.requested
        os.kill(os.getpid(), signal.SIGINT)
        assert stops.requested and stops.signal == signal.SIGINT
    assert signal.getsignal(signal.SIGINT) == previous


def test_a_run_resumes_on_its_base_moved_and_refuses_another(toy_model, tmp_path, one_thread):
    """A run brought back from another machine names its base's new place with --base;
    a base whose files differ is refused."""
    base = tmp_path / "a" / "spacemesh-tiny" / "1"
    shutil.copytree(toy_model.repository, base)
    run = tmp_path / "run"
    config = _config("tiny-local", diffusion_only=True)
    train(TrainOptions(config=config, data=toy_model.data, out=run, steps=1, progress=False,
                       base=base), log=_quiet)
    moved = tmp_path / "b" / "spacemesh-tiny" / "1"
    shutil.move(base, moved)
    summary = train(TrainOptions(config=config, data=toy_model.data, out=run, steps=2,
                                 resume=True, progress=False, base=moved), log=_quiet)
    assert summary.steps == 2
    assert load_checkpoint(summary.checkpoint)["extra"]["base"]["path"] == str(moved.resolve())
    with open(moved / "connectivity.onnx", "ab") as handle:
        handle.write(b"\0")
    with pytest.raises(ValueError, match=r"connectivity\.onnx does not match its manifest"):
        train(TrainOptions(config=config, data=toy_model.data, out=run, steps=3, resume=True,
                           progress=False, base=moved), log=_quiet)


def test_a_warm_started_local_denoiser_starts_as_the_base_denoiser(toy_model, tmp_path,
                                                                    one_thread):
    """``warm_start``: the base's denoiser graph is read back (checked against
    onnxruntime) and grafted into the local-point denoiser, whose local attention starts
    silent, so before any step the run predicts what the base's graph predicts."""
    import onnxruntime as ort

    from spacemesh.nn.base_model import OnnxEncoder
    from spacemesh.runtime.backend import volume_names

    config = _config("tiny-local", diffusion_only=True, warm_start=True, lr=1e-12)
    run = tmp_path / "run"
    summary = train(TrainOptions(config=config, data=toy_model.data, out=run, steps=1,
                                 progress=False, base=toy_model.repository), log=_quiet)
    state = load_checkpoint(summary.checkpoint)
    assert state["config"].train.warm_start
    denoiser = model_from_config(state["config"]).denoiser.eval()
    denoiser.load_state_dict({k[len("denoiser."):]: v for k, v in state["model"].items()
                              if k.startswith("denoiser.")})
    generator = torch.Generator().manual_seed(1)
    points = torch.rand(1, state["config"].encoder.n_points, 3, generator=generator) * 2 - 1
    encoder = OnnxEncoder(toy_model.repository / "encoder.onnx")
    with torch.no_grad():
        volumes = list(encoder(points))
        x_t = torch.randn(1, 20, 4, generator=generator)
        ours = denoiser(x_t, torch.tensor([5]), volumes, points).numpy()
    session = ort.InferenceSession(str(toy_model.repository / "denoiser.onnx"),
                                   providers=["CPUExecutionProvider"])
    feeds = {"x_t": x_t.numpy(), "t": np.array([5], dtype=np.int64)}
    feeds.update(zip(volume_names(len(volumes)), (v.numpy() for v in volumes), strict=True))
    theirs = session.run(None, feeds)[0]
    assert np.abs(ours - theirs).max() < 1e-4 * max(1.0, float(np.abs(theirs).max()))
    fresh = model_from_config(state["config"]).denoiser.eval()
    with torch.no_grad():
        other = fresh(x_t, torch.tensor([5]), volumes, points).numpy()
    assert np.abs(other - theirs).max() > 1e-2  # a fresh denoiser would not agree


def test_a_denoiser_of_another_size_is_not_grafted():
    from spacemesh.nn.denoiser import graft_denoiser

    tiny = model_from_config("tiny").denoiser
    small = model_from_config("small-local").denoiser
    with pytest.raises(ValueError, match="cannot graft the denoiser"):
        graft_denoiser(tiny, small)
