"""The cost model against the real pipeline: estimated and measured time and memory.

For each request of a calibration set (generates on the example torus,
``examples/points.ply``, and on torus clouds of 20,000 to 200,000 points; repairs of
icospheres, a marked region or ``{"auto": "all"}`` with 1 to 20 holes: its planning
counts), a fresh process loads the shipped model, runs the service's warm-up (a
2,048-point sphere, default options), then the request, and reports its wall time and the
peak RSS it added (``VmHWM`` reset after the warm-up; Linux only). The table sets these
beside :data:`spacemesh.runtime.cost.DEFAULT_COST_MODEL`'s estimate, and the number of
seeds that ran (the request's own, plus the model's retry seeds when none passed: the
estimate counts those at an even chance per seed).

With ``--server``, ``spacemesh serve`` (default settings: 30 s deadline, the default
budget) answers issue 37's reproductions and the request the default budget must admit
(``target_vertices=2048&samples=4`` on 200,000 points), and the time each answer took
(``--admitted``: that request only; ``--only 200k-tv2048-samples4 --server --admitted``
times it in-process and through the server).

Usage::

    python bench/bench_cost_model.py [--full] [--server [--admitted]] [--only NAME ...]
                                     [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "points.ply"
#: name -> (kind, cloud, options): cloud is "example", a point count (a sampled torus) or,
#: for a repair, ``[icosphere subdivisions, sphere radius around (0, 0, 1)]`` (a marked
#: region) or ``{"subdivisions", "holes"[, "radius"]}`` (``{"auto": "all"}`` on
#: :func:`bench.heavy_requests.holed_icosphere`).
CASES: dict[str, tuple[str, Any, dict[str, Any]]] = {
    "default": ("generate", "example", {}),
    "tv500": ("generate", "example", {"target_vertices": 500}),
    "tv1000": ("generate", "example", {"target_vertices": 1000}),
    "tv2048": ("generate", "example", {"target_vertices": 2048}),
    "tv4000": ("generate", "example", {"target_vertices": 4000}),
    "samples4": ("generate", "example", {"samples": 4}),
    "samples16": ("generate", "example", {"samples": 16}),
    "steps50-t1": ("generate", "example", {"steps": 50, "start_time": 1.0}),
    "steps200-t1": ("generate", "example", {"steps": 200, "start_time": 1.0}),
    "tv1000-steps40-t1": ("generate", "example", {"target_vertices": 1000, "steps": 40,
                                                  "start_time": 1.0}),
    "tol0.005": ("generate", "example", {"tolerance": 0.005}),
    "tol0.001": ("generate", "example", {"tolerance": 0.001}),
    "20k": ("generate", 20_000, {}),
    "60k": ("generate", 60_000, {}),
    "200k": ("generate", 200_000, {}),
    "200k-tv1000": ("generate", 200_000, {"target_vertices": 1000}),
    "200k-tv2048-samples4": ("generate", 200_000, {"target_vertices": 2048, "samples": 4}),
    "repair-1280": ("repair", [3, 0.3], {}),
    "repair-1280-steps200": ("repair", [3, 0.3], {"steps": 200}),
    "repair-1280-steps1024": ("repair", [3, 0.3], {"steps": 1024}),
    "repair-327680": ("repair", [7, 0.02], {}),
    "repair-auto-20k-1": ("repair", {"subdivisions": 5, "holes": 1}, {}),
    "repair-auto-20k-6": ("repair", {"subdivisions": 5, "holes": 6}, {}),
    "repair-auto-81k-6": ("repair", {"subdivisions": 6, "holes": 6}, {}),
    "repair-auto-327k-1": ("repair", {"subdivisions": 7, "holes": 1}, {}),
    "repair-auto-324k-6": ("repair", {"subdivisions": 7, "holes": 6}, {}),
    "repair-auto-307k-6-wide": ("repair", {"subdivisions": 7, "holes": 6, "radius": 0.2}, {}),
    "repair-auto-79k-20": ("repair", {"subdivisions": 6, "holes": 20}, {}),
}
#: Minutes each: with --full.
LONG_CASES: dict[str, tuple[str, Any, dict[str, Any]]] = {
    "tv2048-steps20-t1": ("generate", "example", {"target_vertices": 2048, "steps": 20,
                                                  "start_time": 1.0}),
    "tv10000": ("generate", "example", {"target_vertices": 10_000}),
    "repair-auto-316k-20": ("repair", {"subdivisions": 7, "holes": 20}, {}),
}
#: Issue 37's first reproduction.
HEAVY = "samples=16&target_vertices=10000&steps=1024&start=points&start_time=1"


def torus_points(count: int, seed: int = 0) -> Any:
    """``count`` points sampled on a torus (as bench/bench_big_cloud.py)."""
    import numpy as np

    from spacemesh.examples import torus_grid
    from spacemesh.primitives import sample_surface

    points, _ = sample_surface(torus_grid(48, 24), count, np.random.default_rng(seed))
    return np.asarray(points, dtype=np.float64)


def _kb(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise KeyError(field)


def run_child(kind: str, cloud: Any, options: dict[str, Any]) -> dict[str, Any]:
    """Measure one request in this (fresh) process."""
    from spacemesh.io import load_points
    from spacemesh.runtime import MeshGenerator
    from spacemesh.runtime.options import GenerateOptions
    from spacemesh_service.engine import fibonacci_sphere

    generator = MeshGenerator.from_repository(None)
    generator.generate(fibonacci_sphere(2048), None, GenerateOptions(seed=1))  # warm-up
    if kind == "repair":
        from bench.heavy_requests import AUTO_ALL, holed_icosphere
        from spacemesh.examples import icosphere
        from spacemesh.repair import AutoPlan, plan_repair, repair_mesh

        if isinstance(cloud, dict):  # an automatic region: planned in the request
            mesh, region = holed_icosphere(**cloud), AUTO_ALL
        else:
            mesh = icosphere(cloud[0])
            region = {"sphere": {"center": [0, 0, 1], "radius": cloud[1]}}
            plan = plan_repair(mesh, region, generator.spec.max_vertices)
        before = _kb("VmRSS")
        Path("/proc/self/clear_refs").write_text("5")  # VmHWM from here on
        started = time.perf_counter()
        if isinstance(cloud, dict):
            plan = plan_repair(mesh, region, generator.spec.max_vertices)
        result = repair_mesh(mesh, region, generator, seed=0, steps=options.get("steps"),
                             plan=plan)
        seconds = time.perf_counter() - started
        work = ({"passes": plan.model_passes, "fills": plan.fills,
                 "fill_vertices2": plan.fill_vertices2, "automatic": True}
                if isinstance(plan, AutoPlan) else {})
        return {"seconds": seconds, "mb": (_kb("VmHWM") - before) / 1024,
                "runs": result.stats.samplings, "faces": mesh.n_faces, "work": work}
    if cloud == "example":
        points, normals = load_points(EXAMPLE)
    else:
        points, normals = torus_points(int(cloud)), None
    before = _kb("VmRSS")
    Path("/proc/self/clear_refs").write_text("5")
    started = time.perf_counter()
    result = generator.generate(points, normals, GenerateOptions(seed=0, **options))
    seconds = time.perf_counter() - started
    return {"seconds": seconds, "mb": (_kb("VmHWM") - before) / 1024,
            "runs": len(result.sample_scores) or 1, "points": len(points),
            "vertices": result.mesh.n_vertices}


def estimate(kind: str, measured: dict[str, Any], options: dict[str, Any]) -> Any:
    """The cost model's estimate of a measured request."""
    import json as _json

    from spacemesh.runtime.cost import DEFAULT_COST_MODEL
    from spacemesh.runtime.options import GenerateOptions
    from spacemesh.runtime.repository import default_model_dir, resolve_version_dir
    from spacemesh.runtime.spec import ModelSpec

    manifest = resolve_version_dir(default_model_dir()) / "manifest.json"
    spec = ModelSpec.from_manifest(_json.loads(manifest.read_text()))
    if kind == "repair":
        return DEFAULT_COST_MODEL.repair(spec, steps=int(options.get("steps", spec.steps)),
                                         faces=int(measured["faces"]),
                                         **measured.get("work", {}))
    resolved = GenerateOptions(seed=0, **options).resolve(spec)
    return DEFAULT_COST_MODEL.generate(spec, resolved, int(measured["points"]))


def calibrate(cases: dict[str, tuple[str, Any, dict[str, Any]]]) -> list[dict[str, Any]]:
    """Measure every case in a fresh process and print it beside its estimate."""
    rows = []
    print(f"{'request':24} {'est s':>8} {'meas s':>8} {'runs':>5} {'est MB':>8} "
          f"{'meas MB':>8}", flush=True)
    for name, (kind, cloud, options) in cases.items():
        done = subprocess.run(
            [sys.executable, __file__, "--child", json.dumps([kind, cloud, options])],
            capture_output=True, text=True, check=True)
        measured = json.loads(done.stdout.strip().splitlines()[-1])
        guess = estimate(kind, measured, options)
        row = {"request": name, "kind": kind, "cloud": cloud, "options": options,
               "estimated_s": round(guess.seconds, 2), "measured_s": round(
                   measured["seconds"], 2), "runs": measured["runs"],
               "estimated_mb": round(guess.memory_mb), "measured_mb": round(measured["mb"])}
        rows.append(row)
        print(f"{name:24} {row['estimated_s']:8.1f} {row['measured_s']:8.1f} "
              f"{row['runs']:5d} {row['estimated_mb']:8.0f} {row['measured_mb']:8.0f}",
              flush=True)
    return rows


def against_server(admitted_only: bool = False) -> list[dict[str, Any]]:
    """Issue 37's reproductions and the admitted request on ``spacemesh serve`` (the
    latter only with ``admitted_only``)."""
    import httpx

    from bench.bench_big_cloud import binary_ply
    from bench.bench_upload_memory import free_port, start_server

    port = free_port()
    server = start_server(port, free_port())
    url = f"http://127.0.0.1:{port}"
    big = binary_ply(200_000)
    requests = [("example, target_vertices=10000", "target_vertices=10000",
                 EXAMPLE.read_bytes()),
                ("200k, " + HEAVY, HEAVY, big),
                ("200k, target_vertices=2048&samples=4", "target_vertices=2048&samples=4",
                 big)]
    if admitted_only:
        requests = requests[-1:]
    rows = []
    try:
        for name, query, data in requests:
            started = time.monotonic()
            reply = httpx.post(f"{url}/generate?{query}&seed=0",
                               files={"file": ("cloud.ply", data)}, timeout=300)
            seconds = time.monotonic() - started
            body = reply.json() if reply.headers.get("content-type", "").startswith(
                "application/problem+json") else {}
            rows.append({"request": name, "status": reply.status_code,
                         "seconds": round(seconds, 2), "type": body.get("type"),
                         "option": body.get("option"), "detail": body.get("detail")})
            print(f"{name}: {reply.status_code} after {seconds:.1f} s "
                  f"{body.get('type', '')} {body.get('detail', '')}", flush=True)
    finally:
        server.terminate()
        server.wait(60)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="also the cases of minutes")
    parser.add_argument("--server", action="store_true",
                        help="also issue 37's requests on spacemesh serve (defaults)")
    parser.add_argument("--admitted", action="store_true",
                        help="with --server: only the request the default budget admits")
    parser.add_argument("--only", nargs="*", help="these cases only (none: no "
                        "calibration)")
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    if args.child:
        print(json.dumps(run_child(*json.loads(args.child))))
        return
    cases = {**CASES, **(LONG_CASES if args.full else {})}
    if args.only is not None:
        cases = {k: v for k, v in {**CASES, **LONG_CASES}.items() if k in args.only}
    result: dict[str, Any] = {"calibration": calibrate(cases)}
    if args.server:
        result["server"] = against_server(args.admitted)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
