"""Evaluate Instant Meshes (``pyinstantmeshes``) as the ``quad`` style, against our pairing.

The solids are the ones ``spacemesh data synth --style quad`` draws: the first attempt of
each index (``default_rng([seed, index])``, target vertex count, ``random_solid``). Each
configuration tessellates every solid; its result is checked as synthesis checks it
(unreferenced vertices dropped, the vertex range, ``canonical``, ``validate_mesh``).
Reported per configuration: valid shapes, rejection causes, seconds per shape (the
tessellation alone), the share of quads by face count, and the vertex count against
the target. ``--retries`` also runs synthesis's retry loop (up to 10 attempts, each a new
solid) and compares what it stores with what pairing stores; ``--png`` draws examples.

pyinstantmeshes 1.0.0, as used here (:func:`instant_meshes`):

- ``remesh()`` returns its result *triangulated* (the binding writes an OBJ and reads it
  back with Instant Meshes' loader, which splits polygons), so ``remesh_file()`` is
  called and the polygons are read from the OBJ it writes. That OBJ has six significant
  digits per coordinate, so the input is normalised to [-1, 1] for the call.
- Every call prints about 100 lines to the C++ stdout; file descriptor 1 points at
  /dev/null during the call.
- ``deterministic=True`` is always passed: the output is then byte-identical on
  repeated runs and with 1 or 2 threads. The default (False) differs from run to run.

Two repairs are tried on its output: :func:`split_nonplanar` (quads folded over sharp
edges to two triangles) and :func:`close_holes` (holes it leaves open closed with one
face). ``im_then_pairing`` is the design that was considered for the ``quad`` style
(extrinsic, then intrinsic, then pairing; the first valid result) and not adopted;
docs/DATA.md ("Quad meshing") has the measurements.

Usage::

    python experiments/eval_quad_instant_meshes.py [--count 40] [--seed 1] [--retries] \
        [--png docs/data/quad_instant_meshes.png]
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import hashlib
import os
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from spacemesh.data.normalize import canonical
from spacemesh.data.shapes import random_solid, solid_to_mesh
from spacemesh.data.styles import isotropic, pair_triangles, segments_for
from spacemesh.data.validate import validate_mesh
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.distance import chamfer_f1, nearest
from spacemesh.metrics.sampling import apply_normalisation, normalisation, sample_mesh
from spacemesh.topology import check_topology

#: Configuration name -> Instant Meshes options; ``"pairing"`` is the ``quad`` style
#: (triangle pairing), ``"exact"`` the CSG triangulation, ``"im_then_pairing"`` the
#: fallback design. ``split``: bent faces to triangles (``split_nonplanar``); ``fill``:
#: holes closed (``close_holes``).
CONFIGS: dict[str, dict | str] = {
    "exact": "exact",
    "pairing": "pairing",
    "im_then_pairing": "im_then_pairing",
    "im": {"extrinsic": False},
    "im_extrinsic": {"extrinsic": True},
    "im_extrinsic_split": {"extrinsic": True, "split": True},
    "im_extrinsic_split_fill": {"extrinsic": True, "split": True, "fill": True},
    "im_split_fill": {"extrinsic": False, "split": True, "fill": True},
    "im_extrinsic_crease30_split": {"extrinsic": True, "crease_angle": 30.0, "split": True},
    "im_extrinsic_pure_quad_split": {"extrinsic": True, "pure_quad": True, "split": True},
}


#: A face whose corners spread more than this along its normal (relative to its
#: diameter, as ``validate.MAX_NONPLANARITY`` measures it) is split by ``split_nonplanar``.
#: A square folded by t scores 0.5 sin(t / 2): 0.1 is a fold of about 23 degrees.
SPLIT_NONPLANARITY = 0.1


# ---------------------------------------------------------------- Instant Meshes
@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Point file descriptor 1 at /dev/null (native code prints there)."""
    try:
        libc = ctypes.CDLL(None)
        fflush = libc.fflush
    except (OSError, AttributeError, TypeError):  # no C library handle (Windows)
        yield
        return
    sys.stdout.flush()
    fflush(None)
    saved, null = os.dup(1), os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    try:
        yield
    finally:
        fflush(None)
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


def _write_obj(path: Path, mesh: PolygonMesh) -> None:
    lines = ["v {!r} {!r} {!r}\n".format(*map(float, p)) for p in mesh.vertices]
    lines += ["f " + " ".join(str(int(i) + 1) for i in f) + "\n" for f in mesh.faces]
    path.write_text("".join(lines))


def _read_obj(path: Path) -> PolygonMesh:
    vertices, faces = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            vertices.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(token.split("/")[0]) - 1 for token in line.split()[1:]])
    mesh = PolygonMesh.from_faces(np.array(vertices, dtype=np.float64).reshape(-1, 3), faces)
    return mesh.remove_unreferenced_vertices()[0]


def instant_meshes(
    mesh: PolygonMesh, target_vertices: int, *, extrinsic: bool = True, **options
) -> PolygonMesh:
    """Instant Meshes' quad-dominant remesh of ``mesh``, with its polygons.

    Parameters
    ----------
    mesh : PolygonMesh
        A closed triangle mesh.
    target_vertices : int
        Instant Meshes gets within about 5% of it.
    extrinsic : bool
        Extrinsic orientation and position fields; on our shapes they give more valid
        meshes than the intrinsic ones.
    **options
        More ``pyinstantmeshes.remesh_file`` options (``crease_angle``, ``pure_quad``,
        ``smooth_iterations`` ...); ``deterministic`` is always True.

    Returns
    -------
    PolygonMesh
        Quads, some triangles and pentagons, in the frame of ``mesh`` (not validated).
    """
    import pyinstantmeshes

    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    centre, scale = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-300)
    unit = mesh.with_vertices((mesh.vertices - centre) / scale)
    with tempfile.TemporaryDirectory(prefix="spacemesh-im-") as folder:
        source, result = Path(folder, "in.obj"), Path(folder, "out.obj")
        _write_obj(source, unit)
        with _quiet_stdout():
            pyinstantmeshes.remesh_file(
                str(source),
                str(result),
                target_vertex_count=int(target_vertices),
                extrinsic=extrinsic,
                **{**options, "deterministic": True},
            )
        out = _read_obj(result)
    return out.with_vertices(out.vertices * scale + centre)


def _nonplanarity(ring: np.ndarray) -> float:
    newell = np.cross(ring, np.roll(ring, -1, axis=0)).sum(axis=0)
    normal = newell / max(float(np.linalg.norm(newell)), 1e-300)
    offsets = (ring - ring.mean(axis=0)) @ normal
    diameter = float(np.linalg.norm(ring[:, None] - ring[None], axis=2).max())
    return float(np.ptp(offsets)) / 2 / max(diameter, 1e-300)


def _cos_fold(v: np.ndarray, t1: list[int], t2: list[int]) -> float:
    n1 = np.cross(v[t1[1]] - v[t1[0]], v[t1[2]] - v[t1[0]])
    n2 = np.cross(v[t2[1]] - v[t2[0]], v[t2[2]] - v[t2[0]])
    return float(n1 @ n2 / max(float(np.linalg.norm(n1) * np.linalg.norm(n2)), 1e-300))


def split_nonplanar(mesh: PolygonMesh, limit: float = SPLIT_NONPLANARITY) -> PolygonMesh:
    """Split faces bent by more than ``limit`` into triangles.

    A bent quad (Instant Meshes wraps quads around sharp edges) becomes two triangles
    along the diagonal that leaves them flatter; a bent n-gon is fanned from its first
    corner.

    Parameters
    ----------
    mesh : PolygonMesh
    limit : float

    Returns
    -------
    PolygonMesh
    """
    v, faces = mesh.vertices, []
    for face in mesh.faces:
        f = [int(x) for x in face]
        if len(f) == 3 or _nonplanarity(v[f]) <= limit:
            faces.append(f)
        elif len(f) == 4:
            a, b, c, d = f
            one, two = ([a, b, c], [a, c, d]), ([a, b, d], [b, c, d])
            faces.extend(one if _cos_fold(v, *one) >= _cos_fold(v, *two) else two)
        else:
            faces.extend([f[0], f[i], f[i + 1]] for i in range(1, len(f) - 1))
    return PolygonMesh.from_faces(v, faces)


def close_holes(mesh: PolygonMesh) -> PolygonMesh:
    """Drop repeated consecutive corners and close each simple hole with one face.

    Instant Meshes leaves holes of more than a few sides open ("Not trying to fill a
    hole of degree 10"). A hole is closed when every boundary vertex has one outgoing
    boundary edge; otherwise the mesh is returned as it is, for the validator to reject.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    PolygonMesh
    """
    faces = []
    for face in mesh.faces:
        f = [int(x) for x in face]
        kept = [x for k, x in enumerate(f) if x != f[k - 1]]
        if len(kept) >= 3:
            faces.append(kept)
    directed = {(f[k], f[(k + 1) % len(f)]) for f in faces for k in range(len(f))}
    following: dict[int, int] = {}
    for a, b in sorted(directed):
        if (b, a) not in directed:
            if a in following:  # a vertex on two holes (or twice on one)
                return PolygonMesh.from_faces(mesh.vertices, faces)
            following[a] = b
    seen: set[int] = set()
    for start in sorted(following):
        if start in seen:
            continue
        loop, current = [start], following[start]
        seen.add(start)
        while current != start and current in following and current not in seen:
            loop.append(current)
            seen.add(current)
            current = following[current]
        if current == start and len(loop) >= 3:
            faces.append(loop[::-1])
    return PolygonMesh.from_faces(mesh.vertices, faces)


# ---------------------------------------------------------------- configurations
def tessellate(config: dict | str, solid, target: int) -> tuple[PolygonMesh, str]:
    """The mesh of one configuration (see CONFIGS) and the method that made it."""
    if config == "exact":  # the CSG triangulation itself: the distances' noise floor
        return solid_to_mesh(solid), "exact"
    if config == "pairing":
        return pair_triangles(isotropic(solid, target, None)), "pairing"
    if config == "im_then_pairing":
        base = solid_to_mesh(solid)
        for extrinsic in (True, False):
            try:
                mesh = instant_meshes(base, target, extrinsic=extrinsic)
            except Exception:
                continue
            mesh = split_nonplanar(close_holes(mesh))
            if mesh.n_faces and not validate_mesh(canonical(mesh)):
                return mesh, "instant_meshes_" + ("extrinsic" if extrinsic else "intrinsic")
        return pair_triangles(isotropic(solid, target, None)), "pairing"
    options = dict(config)
    do_split, do_fill = options.pop("split", False), options.pop("fill", False)
    if options.get("pure_quad"):  # subdivision multiplies the vertices by about 4
        target = max(target // 4, 8)
    mesh = instant_meshes(solid_to_mesh(solid), target, **options)
    if do_fill:
        mesh = close_holes(mesh)
    if do_split:
        mesh = split_nonplanar(mesh)
    return mesh, "instant_meshes"


def check(mesh: PolygonMesh, vertex_range: tuple[int, int]) -> list[str]:
    """Rejection causes, as synthesis (pipeline.prepare_shape) finds them."""
    if mesh.n_faces == 0:
        return ["empty"]
    mesh = mesh.remove_unreferenced_vertices()[0]
    if mesh.n_vertices < vertex_range[0]:
        return ["too_few_vertices"]
    if mesh.n_vertices > vertex_range[1]:
        return ["too_many_vertices"]
    return validate_mesh(canonical(mesh))


# ---------------------------------------------------------------- the evaluation
def draw(rng: np.random.Generator, vertex_range: tuple[int, int]):
    """One attempt's solid, drawn as synth.make_shape draws it (None if CSG fails)."""
    target = int(rng.integers(vertex_range[0], vertex_range[1] + 1))
    try:
        solid, recipe = random_solid(rng, segments_for("quad", target, rng))
    except Exception:
        return None
    return None if solid.is_empty() else (target, solid, recipe)


def fidelity(mesh: PolygonMesh, solid) -> tuple[float, float, float]:
    """(Chamfer distance, F1 at 0.02, Hausdorff distance) to the CSG solid, in its [-1, 1]
    frame, from 10,000 samples on each (as ``spacemesh eval`` scores meshes)."""
    truth = solid_to_mesh(solid)
    centre, scale = normalisation(truth)
    gt = sample_mesh(apply_normalisation(truth, centre, scale)).points
    pred = sample_mesh(apply_normalisation(mesh, centre, scale), seed=1).points
    scores = chamfer_f1(pred, gt)
    hausdorff = max(nearest(pred, gt)[0].max(), nearest(gt, pred)[0].max())
    return scores.chamfer, scores.f1, float(hausdorff)


def evaluate(name: str, config, items, vertex_range) -> list[dict]:
    rows = []
    for index, target, solid, recipe in items:
        start = time.perf_counter()
        try:
            mesh, method = tessellate(config, solid, target)
            seconds = time.perf_counter() - start
            causes = check(mesh, vertex_range)
        except Exception:
            mesh, method = None, "error"
            seconds, causes = time.perf_counter() - start, ["tessellation_error"]
        hist = mesh.degree_histogram() if mesh is not None else {}
        distances = fidelity(mesh, solid) if not causes else (np.nan,) * 3
        rows.append(
            {
                "index": index,
                "target": target,
                "recipe": recipe,
                "genus": int(solid.genus()),
                "mesh": mesh,
                "method": method,
                "distances": distances,
                "seconds": seconds,
                "causes": causes,
                "n_vertices": mesh.n_vertices if mesh is not None else 0,
                "quads": hist.get(4, 0),
                "faces": mesh.n_faces if mesh is not None else 0,
            }
        )
    valid = [r for r in rows if not r["causes"]]
    ratio = np.array([r["n_vertices"] / r["target"] for r in rows if r["mesh"] is not None])
    causes = Counter(c for r in rows for c in r["causes"])
    quads = sum(r["quads"] for r in valid) / max(sum(r["faces"] for r in valid), 1)
    degrees = Counter()
    for r in valid:
        degrees.update(r["mesh"].degree_histogram())
    low, high = np.percentile(ratio, [10, 90])
    methods = Counter(r["method"] for r in valid)
    seconds = np.mean([r["seconds"] for r in rows])
    cd, f1, hd = np.array([r["distances"] for r in valid]).reshape(-1, 3).T
    print(
        f"| `{name}` | {len(valid)} / {len(rows)} | {seconds:.3f} "
        f"| {100 * quads:.0f}% | {dict(sorted(degrees.items()))} "
        f"| {1e3 * np.mean(cd):.2f} | {np.mean(f1):.3f} | {np.median(hd):.3f} "
        f"| {np.median(ratio):.2f} ({low:.2f}-{high:.2f}), "
        f"{100 * np.mean(np.abs(ratio - 1) <= 0.1):.0f}% within 10% "
        f"| {', '.join(f'{k} {v}' for k, v in causes.most_common())} "
        f"| {', '.join(f'{k} {v}' for k, v in methods.most_common())} |",
        flush=True,
    )
    return rows


def describe(rows: list[dict]) -> str:
    """Mean cuts and additions, genus > 0 share of a set of solids."""
    cuts = np.mean([len(r["recipe"].cuts) for r in rows])
    adds = np.mean([len(r["recipe"].additions) for r in rows])
    genus = np.mean([r["genus"] > 0 for r in rows])
    return (
        f"{len(rows)} solids: {cuts:.2f} cuts, {adds:.2f} additions, genus > 0 {100 * genus:.0f}%"
    )


def retries(config, seed: int, count: int, vertex_range, attempts: int = 10) -> None:
    """Synthesis's retry loop (a new solid per attempt) with one configuration."""
    stored, tries, seconds, kept = 0, 0, 0.0, []
    for index in range(count):
        rng = np.random.default_rng([seed, index])
        for _ in range(attempts):
            tries += 1
            drawn = draw(rng, vertex_range)
            if drawn is None:
                continue
            target, solid, recipe = drawn
            start = time.perf_counter()
            try:
                causes = check(tessellate(config, solid, target)[0], vertex_range)
            except Exception:
                causes = ["tessellation_error"]
            seconds += time.perf_counter() - start
            if not causes:
                stored += 1
                kept.append({"recipe": recipe, "genus": int(solid.genus())})
                break
    print(
        f"  stored {stored} / {count} indices in {tries} attempts "
        f"({tries / count:.2f} per index, {seconds / max(stored, 1):.2f} s per stored shape); "
        f"stored {describe(kept)}",
        flush=True,
    )


def determinism(items) -> None:
    """Output digests of 3 runs on each of 5 solids, with and without ``deterministic``."""
    import pyinstantmeshes

    for deterministic in (True, False):
        digests = []
        for _, target, solid, _ in items[:5]:
            runs = set()
            for _ in range(3):
                if deterministic:
                    mesh = instant_meshes(solid_to_mesh(solid), target)
                    data = mesh.vertices.tobytes() + mesh.face_indices.tobytes()
                else:  # the binding's own call, which always passes deterministic=False
                    v, f = _triangles(solid)
                    with _quiet_stdout():
                        out = pyinstantmeshes.remesh(v, f, target_vertex_count=target)
                    data = out[0].tobytes() + out[1].tobytes()
                runs.add(hashlib.sha256(data).hexdigest()[:8])
            digests.append("/".join(sorted(runs)))
        print(f"  deterministic={deterministic}: {' '.join(digests)}", flush=True)


def _triangles(solid) -> tuple[np.ndarray, np.ndarray]:
    mesh = solid_to_mesh(solid)
    return mesh.vertices.astype(np.float32), mesh.face_indices.reshape(-1, 3).astype(np.int32)


def render(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from spacemesh.evaluate.gallery import _draw_mesh, _frame

    good = [r for r in rows if not r["causes"]][:4]
    bad = [r for r in rows if r["causes"] and r["mesh"] is not None and r["mesh"].n_faces][:4]
    fig = plt.figure(figsize=(10.24, 5.12))
    for k, r in enumerate(good + bad):
        ax = fig.add_subplot(2, 4, k + 1, projection="3d")
        mesh = canonical(r["mesh"])
        hist = mesh.degree_histogram()
        degrees = ", ".join(f"{d}:{n}" for d, n in sorted(hist.items()))
        report = check_topology(mesh)
        genus = report.genus if report.genus is not None else "-"
        head = f"V={mesh.n_vertices} g={genus}\n{degrees}"
        if r["causes"]:
            head += "\n" + ", ".join(r["causes"][:2])
        _draw_mesh(ax, mesh, (0.35, 0.55, 0.85) if not r["causes"] else (0.85, 0.45, 0.4))
        _frame(ax, head)
    fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    print(f"  wrote {path}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--vertices", default="128:512")
    parser.add_argument("--configs", default=",".join(CONFIGS))
    parser.add_argument("--retries", action="store_true", help="also run the retry loop")
    parser.add_argument("--png", type=Path, default=None, help="examples of the best IM config")
    args = parser.parse_args()
    try:
        import pyinstantmeshes  # noqa: F401
    except ImportError:
        print("needs pyinstantmeshes (pip install pyinstantmeshes; Python 3.11 or later)")
        return 1
    low, high = (int(x) for x in args.vertices.split(":"))
    vertex_range = (low, high)
    items = []
    for index in range(args.count):
        drawn = draw(np.random.default_rng([args.seed, index]), vertex_range)
        if drawn is not None:
            items.append((index, *drawn))
    print(f"seed {args.seed}, {args.count} indices, {len(items)} solids, vertices {args.vertices}")
    print(
        "| configuration | valid | s/shape | quads (faces) | face degrees | CD x 1e3 | F1 "
        "| Hausdorff (median) | V/target | causes | methods |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    results = {}
    for name in args.configs.split(","):
        results[name] = evaluate(name, CONFIGS[name], items, vertex_range)
    if "pairing" in results:  # distances on the solids where both are valid
        base = results["pairing"]
        for name, rows in results.items():
            both = [k for k, r in enumerate(rows) if not r["causes"] and not base[k]["causes"]]
            if name == "pairing" or not both:
                continue
            mine = np.array([rows[k]["distances"] for k in both])
            theirs = np.array([base[k]["distances"] for k in both])
            print(
                f"`{name}` vs `pairing` on the {len(both)} solids both make valid: CD x 1e3 "
                f"{1e3 * mine[:, 0].mean():.2f} vs {1e3 * theirs[:, 0].mean():.2f}, F1 "
                f"{mine[:, 1].mean():.3f} vs {theirs[:, 1].mean():.3f}, median Hausdorff "
                f"{np.median(mine[:, 2]):.3f} vs {np.median(theirs[:, 2]):.3f}"
            )
    im = [n for n in results if isinstance(CONFIGS[n], dict)]
    if im:
        any_valid = [any(not results[n][k]["causes"] for n in im) for k in range(len(items))]
        print(f"solids valid in at least one Instant Meshes configuration: {sum(any_valid)}")
        best = max(im, key=lambda n: sum(not r["causes"] for r in results[n]))
        valid = [r for r in results[best] if not r["causes"]]
        print(f"all {describe(results[best])}")
        print(f"`{best}` valid on {describe(valid)}")
        print("determinism of", best)
        determinism(items)
        if args.retries:
            for name in ("pairing", best, "im_then_pairing"):
                print(f"retry loop, `{name}`:")
                retries(CONFIGS[name], args.seed, args.count, vertex_range)
        if args.png:
            render(results[best], args.png, f"Instant Meshes ({best}), vertices {args.vertices}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
