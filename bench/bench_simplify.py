"""What the edge collapses (spacemesh.geometry.simplify.simplify) cost on the inputs the
pipeline gives them, and whether another implementation gives the same results.

The inputs are recorded from the shipped model's generates on 4,096 points sampled on
a few meshes: the fitted dense decode that ``finish_geometry`` collapses to the count
asked for (the default path, and ``target_vertices=1000``), and the mesh that
``collapse_flat`` collapses up to its error (``face_type=polygons``). Each is
collapsed ``--repeats`` times and the median seconds printed, with the share of them in
the crossing check. ``--reference REVISION`` loads ``simplify.py`` and
``intersections.py`` as they are at a git revision (e.g. ``main``), times them on the
same inputs, interleaved, and stops with an error at the first result (mesh, vertex
map, stats) that is not byte-identical.

Usage::

    python bench/bench_simplify.py [--repeats 3] [--reference REVISION] [--cache FILE]
        [--meshes FILE ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from types import ModuleType
from typing import Any

import numpy as np

MESHES = "/work/shared/meshes"
DEFAULT_MESHES = [f"{MESHES}/odedstein__meshes__bunny.obj",
                  f"{MESHES}/mikedh__trimesh__fandisk.obj",
                  f"{MESHES}/mikedh__trimesh__ADIS16480.STL"]
#: The generates whose collapses are recorded: (name, generate fields, module whose
#: ``simplify`` the pipeline calls there).
CALLS = [("default", {}, "spacemesh.geometry.finishing"),
         ("target_vertices=1000", {"target_vertices": 1000}, "spacemesh.geometry.finishing"),
         ("polygons", {"face_type": "polygons"}, "spacemesh.geometry.polygons"),
         ("polygons 1000", {"face_type": "polygons", "target_vertices": 1000},
          "spacemesh.geometry.polygons")]
#: Calls timed per mesh and generate (its first; the retries of a default generate with
#: other seeds are alike).
PER_CALL = 2


def record(paths: list[str], model: str | None) -> list[dict[str, Any]]:
    """The arguments of every ``simplify`` call the pipeline makes in :data:`CALLS` on
    4,096 points sampled on each mesh of ``paths``."""
    import importlib

    from spacemesh.io import load_mesh
    from spacemesh.primitives import sample_surface
    from spacemesh.runtime import MeshGenerator

    generator = MeshGenerator.from_repository(model, threads=1)
    cases: list[dict[str, Any]] = []
    for index, path in enumerate(paths):
        points, _ = sample_surface(load_mesh(path), 4096, np.random.default_rng(index))
        for mode, fields, where in CALLS:
            module = importlib.import_module(where)
            original = module.simplify
            label = f"{os.path.basename(path)[:28]} {mode}"

            def spy(mesh, points, normals=None, name=label, _orig=original, **kw):
                cases.append({"name": name, "mesh": mesh, "points": points,
                              "normals": normals, **kw})
                return _orig(mesh, points, normals, **kw)

            module.simplify = spy
            try:
                generator.generate(points, seed=0, **fields)
            finally:
                module.simplify = original
    return cases


def save(path: str, cases: list[dict[str, Any]]) -> None:
    arrays: dict[str, Any] = {}
    for k, case in enumerate(cases):
        mesh = case["mesh"]
        arrays[f"{k}/name"] = np.array(case["name"])
        arrays[f"{k}/vertices"] = mesh.vertices
        arrays[f"{k}/faces"] = mesh.face_indices
        arrays[f"{k}/offsets"] = mesh.face_offsets
        for key in ("points", "normals"):
            if case[key] is not None:
                arrays[f"{k}/{key}"] = case[key]
        for key in ("target_vertices", "max_error"):
            if key in case:
                arrays[f"{k}/{key}"] = np.array(case[key])
    np.savez(path, count=len(cases), **arrays)


def load(path: str) -> list[dict[str, Any]]:
    from spacemesh.mesh import PolygonMesh

    data = np.load(path)
    cases = []
    for k in range(int(data["count"])):
        case: dict[str, Any] = {
            "name": str(data[f"{k}/name"]),
            "mesh": PolygonMesh(data[f"{k}/vertices"], data[f"{k}/faces"],
                                data[f"{k}/offsets"])}
        for key in ("points", "normals"):
            case[key] = data[f"{k}/{key}"] if f"{k}/{key}" in data else None
        for key, kind in (("target_vertices", int), ("max_error", float)):
            if f"{k}/{key}" in data:
                case[key] = kind(data[f"{k}/{key}"])
        cases.append(case)
    return cases


def load_reference(revision: str) -> ModuleType:
    """``simplify.py`` at the git ``revision`` as a module of its own, its crossing test
    (``pairs_cross``) the one of ``intersections.py`` at that revision."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    modules = {}
    for name in ("intersections", "simplify"):
        source = subprocess.run(
            ["git", "show", f"{revision}:model/spacemesh/geometry/{name}.py"], cwd=root,
            check=True, capture_output=True, text=True).stdout
        module = ModuleType(f"reference_{name}")
        sys.modules[module.__name__] = module  # its dataclasses look their module up
        exec(compile(source, f"{revision}:{name}.py", "exec"), module.__dict__)
        modules[name] = module
    modules["simplify"].pairs_cross = modules["intersections"].pairs_cross
    return modules["simplify"]


def run(module: ModuleType, case: dict[str, Any]) -> tuple[float, float, Any]:
    """Seconds of one ``simplify`` call, seconds in its crossing check, and its result."""
    collapser = module._Collapser
    original = collapser._crosses
    spent = [0.0]

    def timed(self, *args):
        start = time.perf_counter()
        try:
            return original(self, *args)
        finally:
            spent[0] += time.perf_counter() - start

    collapser._crosses = timed
    kw = {k: case[k] for k in ("target_vertices", "max_error") if k in case}
    try:
        start = time.perf_counter()
        result = module.simplify(case["mesh"], case["points"], case["normals"], **kw)
        seconds = time.perf_counter() - start
    finally:
        collapser._crosses = original
    return seconds, spent[0], result


def same(a: Any, b: Any) -> bool:
    """Whether two :class:`SimplifyResult` are byte-identical."""
    if (a.vertex_map is None) != (b.vertex_map is None):
        return False
    if a.vertex_map is not None and a.vertex_map.tobytes() != b.vertex_map.tobytes():
        return False
    return (a.mesh.vertices.tobytes() == b.mesh.vertices.tobytes()
            and a.mesh.face_indices.tobytes() == b.mesh.face_indices.tobytes()
            and a.mesh.face_offsets.tobytes() == b.mesh.face_offsets.tobytes()
            and repr(a.stats) == repr(b.stats))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--reference", default=None,
                        help="a git revision whose simplify to time and compare (e.g. main)")
    parser.add_argument("--cache", default="/tmp/bench_simplify_inputs.npz",
                        help="the recorded inputs (recorded when absent)")
    parser.add_argument("--meshes", nargs="*", default=DEFAULT_MESHES)
    parser.add_argument("--model", default=None)
    args = parser.parse_args()
    from spacemesh.evaluate.runner import pin_threads

    pin_threads(1)
    import spacemesh.geometry.simplify as current

    if os.path.exists(args.cache):
        cases = load(args.cache)
    else:
        cases = record(args.meshes, args.model)
        save(args.cache, cases)
    seen: dict[str, int] = {}
    for case in cases:  # the first PER_CALL of each (the pipeline's retries repeat them)
        seen[case["name"]] = seen.get(case["name"], 0) + 1
        case["keep"] = seen[case["name"]] <= PER_CALL
    cases = [case for case in cases if case["keep"]]
    modules = {"current": current}
    if args.reference:
        modules = {"reference": load_reference(args.reference), "current": current}
    print(f"{len(cases)} inputs ({args.cache}), {args.repeats} repeats, median seconds "
          "(crossing check's share)")
    print(f"{'input':<50}{'V in':>6}{'V out':>6}"
          + "".join(f"{name:>22}" for name in modules))
    totals = {name: 0.0 for name in modules}
    for case in cases:
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in modules}
        results: dict[str, Any] = {}
        for _ in range(args.repeats):
            for name, module in modules.items():  # interleaved: the same conditions
                seconds, crossing, results[name] = run(module, case)
                times[name].append((seconds, crossing))
        if args.reference and not same(results["reference"], results["current"]):
            raise SystemExit(f"{case['name']}: the results differ")
        cells = ""
        for name in modules:
            seconds = statistics.median(t for t, _ in times[name])
            crossing = statistics.median(c for _, c in times[name])
            totals[name] += seconds
            cells += f"{seconds:>12.3f} ({crossing:5.3f})"
        out = results["current"].mesh.n_vertices
        print(f"{case['name']:<50}{case['mesh'].n_vertices:>6}{out:>6}{cells}", flush=True)
    print(f"{'total':<62}" + "".join(f"{totals[name]:>12.3f}{'':>10}" for name in modules))
    if args.reference:
        print("every result byte-identical to the reference")


if __name__ == "__main__":
    main()
