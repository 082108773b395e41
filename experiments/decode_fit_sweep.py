"""How the decode's point-fit flips change connectivity on ground-truth vertices.

One model's embeddings of a dataset's shapes (its onnxruntime graphs, computed once),
decoded with the manifest's decode and ``fit_gain`` replaced: no fit (version 5's
decode), each gain of ``--gains`` with the shapes' conditioning points, the chosen gain
with fewer points (``--counts``) and with the points jittered by Gaussian noise
(``--jitter``, in the [-1, 1] frame). Prints a markdown table of the mean decoded edge
F1 and ``next`` accuracy, and the decode time per shape. Choose the gain on a val split
(``--split val`` of a training set), then measure on the held-out set::

    python experiments/decode_fit_sweep.py --data data/qemflip-12k-s5 --split val \\
        --gains 0.1,0.3,0.5,0.7 --counts "" --jitter ""
    python experiments/decode_fit_sweep.py --data data/qemflip-heldout-s2 --gains 0.5 \\
        --counts 1024,512 --jitter 0.005,0.01,0.02,0.04
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from spacemesh.decode import DecodeOptions, decode
from spacemesh.metrics.connectivity import edge_f1_score, next_accuracy
from spacemesh.runtime.pipeline import MeshGenerator
from spacemesh.train.batching import Sample
from spacemesh.train.evaluate import repository_embeddings
from spacemesh.train.loop import load_samples

ROOT = Path(__file__).resolve().parents[1]


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",") if v.strip()]


def _measure(samples: list[Sample], embeddings: list, options: DecodeOptions,
             points: Callable[[Sample], np.ndarray | None], label: str) -> dict:
    f1, nxt, seconds = [], [], 0.0
    for s, emb in tqdm(list(zip(samples, embeddings, strict=True)), desc=label, leave=False):
        start = time.perf_counter()
        result = decode(s.positions, emb, options, points=points(s))
        seconds += time.perf_counter() - start
        f1.append(edge_f1_score(result.connectivity.edges, s.connectivity.edges, s.n_vertices))
        nxt.append(next_accuracy(result.connectivity, s.connectivity))
    return {"label": label, "f1": float(np.mean(f1)), "next": float(np.mean(nxt)),
            "ms": 1e3 * seconds / max(len(samples), 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=ROOT / "models" / "spacemesh-small")
    parser.add_argument("--data", type=Path, default=ROOT / "data" / "qemflip-heldout-s2")
    parser.add_argument("--split", default=None, help="a split (default: all)")
    parser.add_argument("--shapes", type=int, default=100)
    parser.add_argument("--gains", default="0.5", help="fit gains to compare")
    parser.add_argument("--counts", default="1024,512",
                        help="fewer points, with the first gain")
    parser.add_argument("--jitter", default="0.005,0.01,0.02,0.04",
                        help="noise on the points, with the first gain")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0, help="of the jitter")
    args = parser.parse_args()
    gains = _floats(args.gains)
    if not gains:
        parser.error("--gains needs at least one value")
    generator = MeshGenerator.from_repository(args.model, threads=args.threads)
    samples = load_samples(args.data, args.split, generator.spec.max_vertices,
                           limit=args.shapes)
    embeddings = repository_embeddings(generator, samples)
    base = generator.spec.decode
    rows = [_measure(samples, embeddings, replace(base, fit_gain=None), lambda s: None,
                     "no fit (version 5's decode)")]
    for gain in gains:
        rows.append(_measure(samples, embeddings, replace(base, fit_gain=gain),
                             lambda s: s.points, f"fit gain {gain:g}"))
    chosen = replace(base, fit_gain=gains[0])
    for count in (int(c) for c in _floats(args.counts)):
        rows.append(_measure(samples, embeddings, chosen, lambda s, c=count: s.points[:c],
                             f"fit gain {gains[0]:g}, {count} of the points"))
    rng = np.random.default_rng(args.seed)
    for sigma in _floats(args.jitter):
        rows.append(_measure(
            samples, embeddings, chosen,
            lambda s, sd=sigma: s.points + sd * rng.normal(size=s.points.shape),
            f"fit gain {gains[0]:g}, points jittered by {sigma:g}"))
    split = args.split or "all splits"
    print(f"\n{generator.repository.name} version {generator.repository.version}, "
          f"{len(samples)} shapes of {args.data.name} ({split}), ground-truth vertices\n")
    print("| decode | edge F1 | `next` accuracy | decode ms / shape |")
    print("|---|---|---|---|")
    for row in rows:
        print(f"| {row['label']} | {row['f1']:.4f} | {row['next']:.4f} | {row['ms']:.0f} |")


if __name__ == "__main__":
    main()
