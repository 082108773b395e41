"""Benchmark of the inference service: stage latencies, throughput, onnxruntime vs torch.

Usage::

    .venv/bin/python bench/bench_service.py [--model DIR | --config small | --checkpoint RUN]
        [--points 2048] [--requests 12] [--clients 1,4,8] [--steps N] [--threads 2]
        [--torch/--no-torch] [--json OUT]

What it measures (the real server, REST over loopback, one process):

1. Latency per stage and end to end: ``--requests`` sequential ``POST /generate`` of a
   ``--points`` cloud sampled on a torus; stage times come from ``Server-Timing`` (or the
   ``timings`` of a ``no-surface`` problem), end to end is measured by the client.
2. Throughput at each ``--clients`` count, without batching (``max_batch_size=1``) and with
   it (``max_batch_size=8``, 10 ms delay); the mean batch size comes from ``/metrics``.
3. onnxruntime against torch eager on the same weights (needs torch and ``--config`` or
   ``--checkpoint``): each network once, one sampler step, and a whole generation.
4. With ``--steps-sweep 10,20,50``: the median end-to-end latency at each step count and,
   with ``--quality-data DIR`` (a held-out dataset), the pipeline's quality there
   (valid/empty share, Chamfer, F1: :func:`spacemesh.train.evaluate.pipeline_metrics`).

The model: ``--model`` (default: the shipped ``models/spacemesh-small``); ``--config NAME``
exports a randomly initialised model of that configuration (network timings are right,
extraction is not: an untrained model keeps few vertices); ``--checkpoint RUN`` exports a
training run. Prints Markdown tables; ``--json`` also writes the numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

STAGES = ("decode_input", "queue", "encoder", "sampler", "connectivity", "extraction",
          "encode_output")


# ---------------------------------------------------------------------- setup
def export_model(args: argparse.Namespace, directory: Path) -> tuple[Path, Any]:
    """The repository to serve, and the torch model with the same weights (or None)."""
    if args.checkpoint or args.config:
        from spacemesh.export.repository import load_trained_model, write_model_repository
        from spacemesh.nn.model import model_from_config

        base = None  # a connectivity-only run keeps its base's encoder and denoiser graphs
        if args.checkpoint:
            model, state = load_trained_model(args.checkpoint)
            base = state["base"]
        else:
            import torch

            torch.manual_seed(0)
            model = model_from_config(args.config).eval()
        path = write_model_repository(model, directory, name=f"bench-{model.config.name}",
                                      base=base)
        return path, model
    from spacemesh.runtime import default_model_dir

    return Path(args.model) if args.model else default_model_dir(), None


def torus_cloud(count: int) -> np.ndarray:
    """``count`` points on a torus (major radius 2, minor 0.7), in a non-unit frame."""
    from spacemesh.examples import torus_grid
    from spacemesh.primitives import sample_surface

    mesh = torus_grid(48, 24)
    points, _ = sample_surface(mesh, count, np.random.default_rng(0))
    return points * 3.0 + np.array([5.0, -2.0, 1.0])


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def start_server(generator, threads: int, **changes):
    from spacemesh_service.server import BackgroundServer
    from spacemesh_service.settings import Settings

    values = dict(host="127.0.0.1", port=0, grpc_port=0, ort_threads=threads,
                  log_level="warning", request_timeout_s=600, queue_size=256,
                  max_batch_delay_ms=10, max_points=1_000_000)
    values.update(changes)
    return BackgroundServer(Settings(**values), generator).start()


# ---------------------------------------------------------------------- 1. latency
def server_timings(response) -> dict[str, float]:
    """Seconds per stage of one response (Server-Timing, or a problem's timings)."""
    if response.status_code == 200:
        found = re.findall(r"(\w+);dur=([\d.]+)", response.headers.get("server-timing", ""))
        return {k: float(v) / 1000 for k, v in found}
    return dict(response.json().get("timings", {}))


def bench_latency(url: str, cloud: np.ndarray, requests: int, steps: int | None) -> dict:
    import httpx

    body = {"points": cloud.tolist(), "format": "glb"}
    if steps:
        body["steps"] = steps
    stages: dict[str, list[float]] = {s: [] for s in STAGES}
    end_to_end, statuses, faces = [], [], []
    with httpx.Client(base_url=url, timeout=600) as client:
        client.post("/generate", json={**body, "seed": 10_000})  # warm the path
        for seed in range(requests):
            start = time.perf_counter()
            response = client.post("/generate", json={**body, "seed": seed})
            end_to_end.append(time.perf_counter() - start)
            statuses.append(response.status_code)
            if response.status_code == 200:
                faces.append(int(response.headers["x-spacemesh-faces"]))
                assert response.headers["x-spacemesh-closed"] == "true"
            for stage, seconds in server_timings(response).items():
                stages.setdefault(stage, []).append(seconds)
    return {
        "stages_ms": {s: {"median": 1000 * statistics.median(v), "p90": 1000 * percentile(v, 90)}
                      for s, v in stages.items() if v},
        "end_to_end_ms": {"median": 1000 * statistics.median(end_to_end),
                          "p90": 1000 * percentile(end_to_end, 90)},
        "statuses": {str(code): statuses.count(code) for code in sorted(set(statuses))},
        "faces_median": statistics.median(faces) if faces else 0,
    }


# ---------------------------------------------------------------------- 2. throughput
def metric(url: str, name: str) -> float:
    import httpx

    match = re.search(rf"^{re.escape(name)} (\S+)$", httpx.get(url + "/metrics").text, re.M)
    return float(match.group(1)) if match else 0.0


def bench_throughput(generator, threads: int, cloud: np.ndarray, clients: int,
                     batching: bool, per_client: int, steps: int | None) -> dict:
    import httpx

    server = start_server(generator, threads, max_batch_size=8 if batching else 1)
    try:
        body = {"points": cloud.tolist(), "format": "glb"}
        if steps:
            body["steps"] = steps
        barrier = threading.Barrier(clients)

        def client(index: int) -> list[int]:
            codes = []
            with httpx.Client(base_url=server.url, timeout=600) as http:
                barrier.wait()
                for i in range(per_client):
                    seed = index * 1000 + i
                    codes.append(http.post("/generate", json={**body, "seed": seed}).status_code)
            return codes

        start = time.perf_counter()
        with ThreadPoolExecutor(clients) as pool:
            codes = [c for result in pool.map(client, range(clients)) for c in result]
        wall = time.perf_counter() - start
        batches = metric(server.url, "spacemesh_batch_size_count")
        size_sum = metric(server.url, "spacemesh_batch_size_sum")
    finally:
        server.stop()
    return {"clients": clients, "batching": batching, "requests": len(codes),
            "seconds": wall, "requests_per_s": len(codes) / wall,
            "mean_batch_size": size_sum / batches if batches else 0.0,
            "errors": sum(c >= 500 for c in codes)}


# ---------------------------------------------------------------------- 3. ort vs torch
def bench_backends(generator, model, cloud: np.ndarray, steps: int | None,
                   repeats: int) -> dict:
    """Each network, one denoiser step and a whole generation, per backend (batch 1)."""
    from spacemesh.nn.model import TorchBackend
    from spacemesh.runtime import MeshGenerator

    torch_generator = MeshGenerator(TorchBackend(model), generator.spec, name="torch")
    spec = generator.spec
    x, _, _ = generator.prepare_points(cloud, None)
    points = x[None]  # (1, P, C)
    rng = np.random.default_rng(0)
    tokens = rng.standard_normal((1, spec.max_vertices, 4)).astype(np.float32)
    t = np.full(1, spec.schedule.timesteps // 2, np.int64)
    valid = np.ones((1, spec.max_vertices), bool)
    out: dict[str, dict[str, float]] = {}
    for name, gen in (("onnxruntime", generator), ("torch eager", torch_generator)):
        backend = gen.backend
        volumes = backend.encode(points)

        def timed(call) -> float:
            call()  # warm-up
            runs = []
            for _ in range(repeats):
                start = time.perf_counter()
                call()
                runs.append(time.perf_counter() - start)
            return 1000 * statistics.median(runs)

        out[name] = {
            "encoder_ms": timed(lambda b=backend: b.encode(points)),
            "denoiser_step_ms": timed(lambda b=backend, v=volumes: b.denoise(tokens, t, v)),
            "connectivity_ms": timed(
                lambda b=backend, v=volumes: b.connect(tokens[..., :3], valid, v)),
            "generate_ms": timed(lambda g=gen: g.generate(cloud, seed=0, steps=steps)),
        }
    return out


# ---------------------------------------------------------------------- 4. steps
def bench_steps(url: str, generator, cloud: np.ndarray, sweep: list[int], requests: int,
                data: Path | None, shapes: int) -> list[dict]:
    """Latency (and quality, given a dataset) per sampler step count."""
    rows = []
    records = []
    if data is not None:
        from spacemesh.data.shards import first_records

        records = first_records(data, max_vertices=generator.spec.max_vertices, limit=shapes)
    for steps in sweep:
        row: dict[str, Any] = {"steps": steps,
                               **bench_latency(url, cloud, requests, steps)["end_to_end_ms"]}
        if records:
            from spacemesh.train.evaluate import pipeline_metrics

            row["quality"] = pipeline_metrics(generator, records, steps=steps)
        rows.append(row)
    return rows


# ---------------------------------------------------------------------- report
def report(results: dict) -> str:
    lines = [f"model: {results['model']} | steps: {results['steps']} | points: "
             f"{results['points']} | onnxruntime threads: {results['threads']} | "
             f"cpus: {results['cpus']} | load average at start: {results['load']}", ""]
    latency = results["latency"]
    lines += ["| stage | median ms | p90 ms |", "|---|---:|---:|"]
    for stage, v in latency["stages_ms"].items():
        lines.append(f"| {stage} | {v['median']:.1f} | {v['p90']:.1f} |")
    e2e = latency["end_to_end_ms"]
    lines.append(f"| **end to end (client)** | **{e2e['median']:.1f}** | {e2e['p90']:.1f} |")
    lines += ["", f"statuses: {latency['statuses']}, median faces: {latency['faces_median']}", ""]
    if results["throughput"]:
        lines += ["| clients | batching | requests/s | mean batch | requests | errors |",
                  "|---:|---|---:|---:|---:|---:|"]
    for row in results["throughput"]:
        lines.append(f"| {row['clients']} | {'on (max 8)' if row['batching'] else 'off'} | "
                     f"{row['requests_per_s']:.2f} | {row['mean_batch_size']:.2f} | "
                     f"{row['requests']} | {row['errors']} |")
    if results.get("steps_sweep"):
        lines += ["", "| steps | end to end median ms | p90 ms | valid | empty | "
                  "Chamfer median | F1 mean |", "|---:|---:|---:|---:|---:|---:|---:|"]
        for row in results["steps_sweep"]:
            q = row.get("quality", {})
            cells = [f"{q[k]:.3f}" if k in q else "—" for k in
                     ("valid", "empty", "chamfer_median", "f1_mean")]
            lines.append(f"| {row['steps']} | {row['median']:.1f} | {row['p90']:.1f} | "
                         + " | ".join(cells) + " |")
    if results.get("backends"):
        lines += ["", "| backend | encoder ms | denoiser step ms | connectivity ms | "
                  "generate ms |", "|---|---:|---:|---:|---:|"]
        for name, v in results["backends"].items():
            lines.append(f"| {name} | {v['encoder_ms']:.1f} | {v['denoiser_step_ms']:.2f} | "
                         f"{v['connectivity_ms']:.1f} | {v['generate_ms']:.1f} |")
    return "\n".join(lines)


def main() -> None:
    """Run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--model", type=Path, default=None)
    source.add_argument("--config", default=None, help="export a fresh model of this config")
    source.add_argument("--checkpoint", type=Path, default=None, help="export a training run")
    parser.add_argument("--points", type=int, default=2048)
    parser.add_argument("--requests", type=int, default=12)
    parser.add_argument("--clients", default="1,4,8")
    parser.add_argument("--per-client", type=int, default=3)
    parser.add_argument("--steps", type=int, default=None, help="default: the model's")
    parser.add_argument("--threads", type=int, default=2,
                        help="threads that run the networks' batch items (--ort-threads)")
    parser.add_argument("--torch", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--steps-sweep", default="", help="e.g. 10,20,30,50")
    parser.add_argument("--quality-data", type=Path, default=None,
                        help="held-out dataset for the quality of each swept step count")
    parser.add_argument("--quality-shapes", type=int, default=16)
    parser.add_argument("--no-throughput", dest="throughput", action="store_false")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()

    from spacemesh.runtime import MeshGenerator
    from spacemesh_service.server import configure_logging

    configure_logging("warning")
    with tempfile.TemporaryDirectory() as tmp:
        path, model = export_model(args, Path(tmp))
        generator = MeshGenerator.from_repository(path, threads=args.threads)
        cloud = torus_cloud(args.points)
        steps = args.steps or generator.spec.steps
        results: dict[str, Any] = {
            "model": f"{generator.name} ({path})", "steps": steps, "points": args.points,
            "threads": args.threads, "cpus": len(os.sched_getaffinity(0)),
            "load": round(os.getloadavg()[0], 2),
        }
        server = start_server(generator, args.threads, max_batch_size=1)
        try:
            results["latency"] = bench_latency(server.url, cloud, args.requests, steps)
            if args.steps_sweep:
                sweep = [int(v) for v in args.steps_sweep.split(",")]
                results["steps_sweep"] = bench_steps(
                    server.url, generator, cloud, sweep, args.requests, args.quality_data,
                    args.quality_shapes)
        finally:
            server.stop()
        results["throughput"] = [
            bench_throughput(generator, args.threads, cloud, int(c), batching,
                             args.per_client, steps)
            for c in args.clients.split(",") for batching in (False, True)
        ] if args.throughput else []
        if args.torch and model is not None:
            import torch

            torch.set_num_threads(args.threads)
            results["backends"] = bench_backends(generator, model, cloud, steps, args.repeats)
        elif args.torch:
            results["backends_note"] = ("torch comparison needs --config or --checkpoint "
                                        "(a repository holds no torch weights)")
    print(report(results))
    if args.json:
        args.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
