"""Run our model and the baselines on the same inputs, score them, and write the report.

For every shape (a dataset record, or a mesh file normalised and sampled):

1. the ground truth is put in its [-1, 1] frame and sampled once
   (:class:`spacemesh.metrics.Reference`); the input points are the shape's 2048
   conditioning points, in the same frame;
2. normals are *estimated* from the points (:func:`spacemesh.baselines.estimate_normals`),
   as a user would; the baselines get them, and so does our model if it reads normals;
   the points' *true* normals (the ground truth's face normals, kept by
   :func:`mesh_shapes` and the datasets) go to the ``psr_true`` baselines and to the
   ``normals`` mode of our pipeline;
3. ours (``MeshGenerator.generate``), then PSR, PSR* (PSR decimated to our vertex count
   for that shape, or the ground truth's when ours failed or with
   ``psr_star_target="gt"``), PSR* from the true normals and BPA;
4. each mesh is scored with :func:`spacemesh.metrics.score_mesh`; the ground truth itself,
   sampled with another seed, is scored too (the ``gt`` row: the best any method can get
   with 10,000 samples).

Threads are pinned (:func:`pin_threads`) so that timings compare like with like: the
BLAS/OpenMP variables are set before pymeshlab or onnxruntime is imported, Poisson runs
with ``threads=1``, and onnxruntime gets the same count (the CLI passes it).
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh.evaluate.gallery import GalleryRow, render_gallery
from spacemesh.mesh import PolygonMesh
from spacemesh.metrics.compare import METRIC_KEYS, MetricOptions, Reference, score_mesh
from spacemesh.metrics.quality import corner_angles, edge_lengths
from spacemesh.metrics.report import (
    markdown_tables,
    method_label,
    plot_histograms,
    summarise,
    write_csv,
)
from spacemesh.metrics.sampling import apply_normalisation, normalisation
from spacemesh.threads import limit_threads
from spacemesh.typed import FloatArray

#: Baselines the runner knows, in table order. ``psr_star``: screened Poisson from
#: normals estimated from the points, decimated to our vertex count; ``psr_star_gt``: the
#: same at the ground truth's vertex count; ``psr_true`` and ``psr_true_gt``: the same
#: two from the points' true normals (the strong baseline).
BASELINES = ("psr", "psr_star", "psr_star_gt", "psr_true", "psr_true_gt", "bpa")
#: Baselines made from screened Poisson, with the normals each reads ("estimated" or
#: "true") and the vertex count it is decimated to (None: PSR as it comes).
POISSON_BASELINES: dict[str, tuple[str, str | None]] = {
    "psr": ("estimated", None),
    "psr_star": ("estimated", "ours"),
    "psr_star_gt": ("estimated", "gt"),
    "psr_true": ("true", "ours"),
    "psr_true_gt": ("true", "gt"),
}
#: Modes of our pipeline the runner knows: the method name of each row, the generate
#: options it runs with (``gt``: ``target_vertices`` = the ground truth's count, the
#: compactness row; ``normals``: the points' true normals go with them) and, for
#: the ablations, what it changes in the geometry stage
#: (:class:`spacemesh.geometry.GeometryOptions` fields; ``fit``: VertexFitOptions fields).
MODES: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {
    "default": ("ours", {}, {}),
    "raw": ("ours_raw", {"raw": True}, {}),
    "paper": ("ours_paper", {"raw": True, "start": "noise"}, {}),
    "samples4": ("ours_s4", {"samples": 4}, {}),
    "denoise_low": ("ours_denoise_low", {"start_time": 0.02}, {}),
    "denoise": ("ours_denoise", {"start_time": 0.05}, {}),
    "gt_denoise": ("ours_gt_denoise", {"start_time": 0.05}, {}),
    "gt": ("ours_gt", {}, {}),
    "normals": ("ours_normals", {}, {}),
    "no_fit": ("ours_no_fit", {}, {"fit": {"iterations": 0}}),
    "no_flips": ("ours_no_flips", {}, {"flips": False}),
    "no_sharp": ("ours_no_sharp", {}, {"fit": {"plane_weight": 0.0}}),
    # a dense decode simplified to the count asked for (spacemesh.geometry.simplify)
    "dense2": ("ours_dense2", {}, {"dense_factor": 2.0}),
    "dense4": ("ours_dense4", {}, {"dense_factor": 4.0}),
    # a size that follows the shape: the smallest mesh within a tolerance
    "tol2": ("ours_tol2", {"tolerance": 0.002}, {}),
    "tol3": ("ours_tol3", {"tolerance": 0.003}, {}),
}
#: Conditioning points sampled on a mesh file (as in the datasets).
N_POINTS = 2048


def pin_threads(threads: int) -> None:
    """Cap BLAS/OpenMP, torch and onnxruntime threads (call before pymeshlab/onnxruntime
    are imported): :func:`spacemesh.threads.limit_threads`, the one meaning of
    ``--threads``.

    Parameters
    ----------
    threads : int
        At least 1 (0: one per core).
    """
    limit_threads(threads)


@dataclass(frozen=True)
class EvalShape:
    """One evaluation input.

    Attributes
    ----------
    shape_id : str
    mesh : PolygonMesh
        The ground truth (any frame; scored in its own [-1, 1] frame).
    points : (P, 3) float
        Conditioning points on the ground truth, in the mesh's frame.
    category : str
        e.g. the dataset style or the mesh's category.
    normals : (P, 3) float, optional
        The points' true normals (the ground truth's normal where each was sampled).
    """

    shape_id: str
    mesh: PolygonMesh
    points: FloatArray
    category: str = ""
    normals: FloatArray | None = None


def dataset_shapes(
    directory: str | Path, split: str = "test", limit: int | None = None
) -> list[EvalShape]:
    """The shapes of a shard dataset (``spacemesh data synth`` / ``data import``).

    Parameters
    ----------
    directory : path
    split : {"train", "val", "test", "all"}
    limit : int, optional
        At most this many shapes (the first ones).

    Returns
    -------
    list of EvalShape
    """
    from spacemesh.data.shards import open_dataset

    dataset = open_dataset(directory, None if split == "all" else split)
    count = len(dataset) if limit is None else min(limit, len(dataset))
    return [EvalShape(r.shape_id, r.mesh, r.points, r.style, r.normals)
            for r in dataset[:count]]


def mesh_shapes(
    paths: Sequence[str | Path],
    *,
    categories: Sequence[str] | None = None,
    points: int = N_POINTS,
    seed: int = 0,
) -> list[EvalShape]:
    """Mesh files as evaluation shapes: normalised, with ``points`` sampled points each
    (and their true normals).

    Parameters
    ----------
    paths : sequence of path
    categories : sequence of str, optional
        One per path.
    points : int
    seed : int
        Sampling seed (combined with the file's position in ``paths``).

    Returns
    -------
    list of EvalShape
    """
    from spacemesh.io import load_mesh
    from spacemesh.primitives import normalize, sample_surface

    shapes = []
    for i, path in enumerate(paths):
        mesh, _, _ = normalize(load_mesh(path))
        cloud, normals = sample_surface(mesh, points, np.random.default_rng([seed, i]))
        category = categories[i] if categories is not None else ""
        shapes.append(EvalShape(Path(path).name, mesh, cloud, category, normals))
    return shapes


def load_shapes(
    source: str | Path, *, split: str = "test", limit: int | None = None
) -> list[EvalShape]:
    """A dataset folder (with ``manifest.json``) or a folder of mesh files, as shapes."""
    from spacemesh.data.importer import find_mesh_files
    from spacemesh.data.shards import MANIFEST

    source = Path(source)
    if (source / MANIFEST).is_file():
        return dataset_shapes(source, split, limit)
    if not source.is_dir():
        raise FileNotFoundError(f"{source}: no such dataset or mesh folder")
    files = find_mesh_files(source)
    if not files:
        raise FileNotFoundError(f"{source} has neither {MANIFEST} nor mesh files")
    return mesh_shapes(files[:limit] if limit else files)


@dataclass
class EvalResult:
    """Everything one evaluation run produced.

    Attributes
    ----------
    rows : list of dict
        One per (shape, method); see :mod:`spacemesh.metrics.report`.
    distributions : dict
        Method -> ``{"edge_lengths": [...], "corner_angles": [...]}`` (one array per shape).
    gallery : list of GalleryRow
    config : dict
        How the run was made (model, baselines, seeds, metric options, threads).
    """

    rows: list[dict[str, Any]] = field(default_factory=list)
    distributions: dict[str, dict[str, list[np.ndarray]]] = field(default_factory=dict)
    gallery: list[GalleryRow] = field(default_factory=list)
    config: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, dict[str, Any]]:
        """Per-method aggregates (:func:`spacemesh.metrics.report.summarise`)."""
        return summarise(self.rows)


def gallery_indices(count: int, wanted: int) -> set[int]:
    """``wanted`` shape indices spread evenly over ``count`` shapes."""
    if wanted <= 0 or count == 0:
        return set()
    return {int(i) for i in np.linspace(0, count - 1, min(wanted, count)).round()}


def _timed(
    make: Callable[..., PolygonMesh], *args: Any, **kwargs: Any
) -> tuple[PolygonMesh | None, str, float]:
    """Run one method: (mesh or None, ``"ok"`` or why it failed, seconds)."""
    start = time.perf_counter()
    try:
        mesh = make(*args, **kwargs)
    except Exception as error:  # a method failing is a result, not a crash
        return None, f"failed: {type(error).__name__}: {error}"[:200], time.perf_counter() - start
    status = "ok" if mesh.n_faces else "failed: empty mesh"
    return mesh, status, time.perf_counter() - start


def _generate(
    generator: Any, points: FloatArray, normals: FloatArray | None, declared_open: set[int],
    **options: Any
) -> PolygonMesh:
    """Our mesh; its ``id`` joins ``declared_open`` when its fit report says it is an
    open surface (valid with boundary edges)."""
    result = generator.generate(points, normals, **options)
    fit = getattr(result, "fit", None)  # stand-in generators may have no fit report
    if fit is not None and fit.open_surface:
        declared_open.add(id(result.mesh))
    return result.mesh


@contextlib.contextmanager
def _geometry_changed(generator: Any, changes: dict[str, Any]) -> Iterator[None]:
    """The generator's geometry stage with ``changes`` for the duration (ablations)."""
    if not changes:
        yield
        return
    from dataclasses import replace

    spec = generator.spec
    geometry = spec.geometry
    fit = replace(geometry.fit, **changes.get("fit", {}))
    others = {k: v for k, v in changes.items() if k != "fit"}
    generator.spec = replace(spec, geometry=replace(geometry, fit=fit, **others))
    try:
        yield
    finally:
        generator.spec = spec


def parse_modes(text: str) -> list[str]:
    """``"default,raw"`` -> a checked list of :data:`MODES` names."""
    names = [m.strip() for m in text.split(",") if m.strip()]
    unknown = [m for m in names if m not in MODES]
    if unknown or not names:
        raise ValueError(f"unknown modes {unknown or text!r}; choose from {', '.join(MODES)}")
    return list(dict.fromkeys(names))


def corrupt_points(points: FloatArray, *, noise: float = 0.0, partial: bool = False,
                   seed: int | list[int] = 0, outliers: float = 0.0) -> FloatArray:
    """Conditioning points as a scan would give them: with ``partial`` only one side
    (the points at or above the median x), Gaussian noise of ``noise`` times the
    bounding-box diagonal, and ``outliers`` times as many points again spread uniformly
    over the bounding box (appended after the surface points).

    Parameters
    ----------
    points : (P, 3) float
    noise : float
    partial : bool
    seed : int or list of int
    outliers : float
        Outliers added, as a fraction of the (kept) points.

    Returns
    -------
    (P' + round(outliers * P'), 3) float64
    """
    points = np.asarray(points, dtype=np.float64)[scan_kept(points, partial)]
    points = _noisy(points, noise, seed) if noise > 0 else points
    return _with_outliers(points, outliers, seed) if outliers > 0 else points


def scan_kept(points: FloatArray, partial: bool) -> np.ndarray:
    """(P,) bool: the points a one-sided scan keeps (all of them unless ``partial``), so
    that their true normals can follow them."""
    points = np.asarray(points)
    if not partial:
        return np.ones(len(points), dtype=bool)
    return points[:, 0] >= np.median(points[:, 0])


def _noisy(points: FloatArray, noise: float, seed: int | list[int]) -> FloatArray:
    """``points`` with Gaussian noise of ``noise`` times their bounding-box diagonal."""
    rng = np.random.default_rng(seed)
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    return points + rng.normal(scale=noise * diagonal, size=points.shape)


def _with_outliers(points: FloatArray, share: float, seed: int | list[int]) -> FloatArray:
    """``points`` and ``round(share * P)`` more drawn uniformly in their bounding box."""
    seeds = [seed] if isinstance(seed, int) else list(seed)
    rng = np.random.default_rng([*seeds, 1])  # not the noise's stream
    low, high = points.min(axis=0), points.max(axis=0)
    extra = rng.uniform(low, high, size=(round(share * len(points)), 3))  # (O, 3)
    return np.concatenate([points, extra])


def _row(
    shape: EvalShape,
    method: str,
    mesh: PolygonMesh | None,
    status: str,
    seconds: float,
    reference: Reference,
    seed: list[int],
    *,
    open_surface: bool = False,
) -> dict[str, Any]:
    row: dict[str, Any] = {
        "shape_id": shape.shape_id,
        "method": method,
        "category": shape.category,
        "status": status,
        "seconds": seconds,
    }
    if mesh is not None and mesh.n_faces:
        row.update(score_mesh(mesh, reference, seed=seed, open_surface=open_surface))
        if math.isnan(row["cd"]):
            row["status"] = "failed: no surface"
    else:
        row.update({k: math.nan for k in METRIC_KEYS})
        row.update(
            n_vertices=0,
            n_faces=0,
            manifold=False,
            watertight=False,
            oriented=False,
            valid=False,
            components=0,
            pieces=0,
            genus=0,
            topology=False,
            degrees="",
        )
    return row


def run_evaluation(
    shapes: Sequence[EvalShape],
    *,
    generator: Any = None,
    baselines: Sequence[str] = BASELINES,
    seed: int = 0,
    steps: int | None = None,
    gallery: int = 4,
    threads: int = 1,
    psr_star_target: str = "ours",
    options: MetricOptions | None = None,
    progress: bool = True,
    modes: Sequence[str] = ("default",),
    noise: float = 0.0,
    partial: bool = False,
    outliers: float = 0.0,
) -> EvalResult:
    """Run ours and the baselines on every shape and score them (see the module doc).

    Parameters
    ----------
    shapes : sequence of EvalShape
    generator : MeshGenerator, optional
        Our model (:class:`spacemesh.runtime.MeshGenerator`); without it only the
        baselines run.
    baselines : sequence of str
        Any of :data:`BASELINES`.
    seed : int
        Seed of our sampler and of the metric samples.
    steps : int, optional
        Sampler steps (default: the model's).
    gallery : int
        Shapes kept for the gallery.
    threads : int
        Solver threads of the baselines (Poisson).
    psr_star_target : {"ours", "gt"}
        Vertex count PSR* is decimated to: our output's for the shape (the first of
        ``modes``; the paper's PSR*), or the ground truth's (for runs whose model is
        not yet meaningful).
    options : MetricOptions, optional
    progress : bool
        Show a tqdm progress bar.
    modes : sequence of str
        Our pipeline's modes (:data:`MODES`), one row each.
    noise : float
        Gaussian noise on the conditioning points, as a fraction of their diagonal.
    partial : bool
        Keep only the points of one side (:func:`corrupt_points`).
    outliers : float
        Uniform outliers added, as a fraction of the points (:func:`corrupt_points`);
        the ``normals`` mode then has no true normals to give.

    Returns
    -------
    EvalResult
    """
    from tqdm import tqdm

    from spacemesh.baselines import ball_pivoting, estimate_normals, psr_star, screened_poisson

    unknown = [b for b in baselines if b not in BASELINES]
    if unknown:
        raise ValueError(f"unknown baselines {unknown}; choose from {', '.join(BASELINES)}")
    if psr_star_target not in ("ours", "gt"):
        raise ValueError(f"psr_star_target must be 'ours' or 'gt', not {psr_star_target!r}")
    options = options or MetricOptions()
    ours_methods = [MODES[m][0] for m in parse_modes(",".join(modes))] if generator else []
    methods = ours_methods + list(baselines) + ["gt"]
    result = EvalResult(
        distributions={m: {"edge_lengths": [], "corner_angles": []} for m in methods},
        config={
            "seed": seed,
            "steps": steps,
            "baselines": list(baselines),
            "threads": threads,
            "psr_star_target": psr_star_target,
            "shapes": len(shapes),
            "metrics": options.__dict__.copy(),
            "model": getattr(generator, "name", None),
            "modes": list(modes),
            "noise": noise,
            "partial": partial,
            "outliers": outliers,
        },
    )
    keep = gallery_indices(len(shapes), gallery)
    bar = tqdm(shapes, desc="eval", unit="shape", disable=not progress, dynamic_ncols=True)
    for index, shape in enumerate(bar):
        centre, scale = normalisation(shape.mesh)
        gt = apply_normalisation(shape.mesh, centre, scale)
        points: FloatArray = (np.asarray(shape.points, np.float64) - centre) / scale  # (P, 3)
        kept = scan_kept(points, partial)
        points = corrupt_points(points, noise=noise, partial=partial, seed=[seed, index],
                                outliers=outliers)
        true_normals = (None if shape.normals is None or outliers > 0
                        else np.asarray(shape.normals, np.float64)[kept])  # (P', 3)
        reference = Reference.from_mesh(gt, seed=[seed, index, 0], options=options)
        normals = estimate_normals(points)  # (P, 3), what every method may use
        meshes: dict[str, tuple[PolygonMesh | None, str, float]] = {}
        declared_open: set[int] = set()  # ids of our meshes whose fit report says open
        if generator is not None:
            wants_normals = bool(getattr(getattr(generator, "spec", None), "normals", False))
            for mode in parse_modes(",".join(modes)):
                method, extra, geometry = MODES[mode]
                bar.set_postfix_str(method)
                extra = dict(extra, seed=seed, steps=steps)
                if mode in ("gt", "gt_denoise"):
                    extra["target_vertices"] = gt.n_vertices
                given = normals if wants_normals else None
                if mode == "normals":
                    given = true_normals
                    if given is None:
                        meshes[method] = (None, "failed: no true normals", 0.0)
                        continue
                with _geometry_changed(generator, geometry):
                    meshes[method] = _timed(_generate, generator, points, given,
                                            declared_open, **extra)
        # "ours": the first mode's mesh (the default's when it runs first)
        first = next(iter(meshes.values()), (None,))
        ours = first[0] if psr_star_target == "ours" else None
        ours_count = ours.n_vertices if ours is not None and ours.n_faces else gt.n_vertices
        poisson: dict[str, tuple[PolygonMesh | None, str, float]] = {}
        for name in (b for b in baselines if b in POISSON_BASELINES):
            which, target = POISSON_BASELINES[name]
            if which not in poisson:
                bar.set_postfix_str(f"psr ({which} normals)")
                if which == "true" and true_normals is None:
                    poisson[which] = (None, "failed: no true normals", 0.0)
                else:
                    oriented = normals if which == "estimated" else true_normals
                    poisson[which] = _timed(screened_poisson, points, oriented,
                                            threads=threads)
            psr = poisson[which]
            if target is None or psr[0] is None:
                meshes[name] = psr
            else:
                count = ours_count if target == "ours" else gt.n_vertices
                star = _timed(psr_star, psr[0], count)
                meshes[name] = (star[0], star[1], star[2] + psr[2])
        if "bpa" in baselines:
            bar.set_postfix_str("bpa")
            meshes["bpa"] = _timed(ball_pivoting, points, normals)
        meshes["gt"] = (gt, "ok", 0.0)
        bar.set_postfix_str("metrics")
        for k, method in enumerate(methods):
            mesh, status, seconds = meshes[method]
            result.rows.append(
                _row(shape, method, mesh, status, seconds, reference, [seed, index, k + 1],
                     open_surface=mesh is not None and id(mesh) in declared_open)
            )
            if mesh is not None and mesh.n_faces:
                result.distributions[method]["edge_lengths"].append(edge_lengths(mesh))
                result.distributions[method]["corner_angles"].append(corner_angles(mesh))
        if index in keep:
            result.gallery.append(
                GalleryRow(shape.shape_id, points, {m: v[0] for m, v in meshes.items()})
            )
    bar.close()
    return result


def write_report(
    result: EvalResult,
    out: str | Path,
    *,
    title: str = "SpaceMesh evaluation",
    command: str | None = None,
) -> dict[str, Path]:
    """Write the tables, the per-shape CSV, the histograms and the gallery.

    Parameters
    ----------
    result : EvalResult
    out : path
        Report folder (created).
    title : str
    command : str, optional
        The command that made the run, recorded in the markdown.

    Returns
    -------
    dict of str to Path
        ``table`` (``table.md``), ``csv`` (``per_shape.csv``), ``summary``
        (``summary.json``), ``histograms`` (``histograms.png``) and ``gallery``
        (``gallery.png``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = result.summary()
    paths = {"csv": write_csv(result.rows, out / "per_shape.csv")}
    text = [f"# {title}", ""]
    if command:
        text += ["```", command, "```", ""]
    text += [markdown_tables(summary)]
    paths["table"] = out / "table.md"
    paths["table"].write_text("\n".join(text))
    paths["summary"] = out / "summary.json"
    paths["summary"].write_text(
        json.dumps(
            _finite({"config": result.config, "summary": summary}), indent=2, default=_json_default
        )
        + "\n"
    )
    paths["histograms"] = plot_histograms(
        result.distributions, summary, out / "histograms.png", title=title
    )
    labels = {"points": "input points", "gt": "ground truth"}
    labels.update({m: method_label(m) for m in ("ours", "psr", "psr_star", "bpa")})
    paths["gallery"] = render_gallery(
        result.gallery, out / "gallery.png", labels=labels, title=title
    )
    return paths


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def _finite(value: Any) -> Any:
    """``value`` with every NaN float replaced by None (strict JSON)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, float) and math.isnan(value):
        return None
    return value
