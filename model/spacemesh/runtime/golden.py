"""The golden check: a model's graphs must reproduce the outputs its manifest recorded.

The sha256 of a file says that its bytes are the ones the manifest lists, not that they
are the weights that were trained: a file rewritten together with its hash, or a graph
that another onnxruntime build computes differently, passes it. So the manifest's
``golden`` section records what each graph gave for a fixed, deterministic input when
the model was exported, and :meth:`spacemesh.runtime.repository.ModelRepository.load`
runs the same input again and refuses a model whose outputs moved.

The input is built from the model's manifest alone, with integer hashing
(:func:`hash_uniform`) rather than a numpy random stream, so every machine builds the
same bytes: the encoder sees ``n_points`` points on an ellipsoid, the denoiser and the
connectivity network see ``max_vertices`` tokens and the encoder's volumes.

Per output the section keeps its shape, its mean and root mean square, :data:`SAMPLES`
values at fixed indices and :data:`PROJECTIONS` projections of the whole output on fixed
pseudo-random directions (each moves by about the rms of any change, wherever in the
output it is). An output passes when its shape is the same and the mean, the rms, every
sampled value and every projection are within ``tolerance`` times the recorded rms
(:data:`TOLERANCE`). Thread counts change nothing here, and onnxruntime with its graph
optimisations off (other fused kernels, as on another CPU) moves the shipped model's
outputs by 3e-6 of their rms; a changed weight moves them by far more.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from spacemesh.runtime.backend import OnnxBackend, volume_names

#: Manifest key of the section.
SECTION = "golden"
#: Values sampled per output.
SAMPLES = 16
#: Random projections per output.
PROJECTIONS = 8
#: Allowed deviation, relative to an output's recorded rms.
TOLERANCE = 5e-4
#: Seed of the golden input.
SEED = 0
#: Floor of the rms used as the scale (an all-zero output is compared absolutely).
_MIN_SCALE = 1e-6
_MASK64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _splitmix64(values: np.ndarray) -> np.ndarray:
    """SplitMix64 of ``values`` (uint64, wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        z = (values + np.uint64(0x9E3779B97F4A7C15)) & _MASK64
        z = ((z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)) & _MASK64
        z = ((z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)) & _MASK64
        return z ^ (z >> np.uint64(31))


def hash_uniform(count: int, seed: int, stream: int = 0) -> np.ndarray:
    """``count`` numbers in [-1, 1), the same on every machine and numpy version.

    Parameters
    ----------
    count : int
    seed, stream : int
        Different pairs give independent sequences.

    Returns
    -------
    (count,) float64
    """
    base = np.uint64((seed * 1_000_003 + stream * 7_919) & 0xFFFFFFFF) << np.uint64(32)
    bits = _splitmix64(np.arange(count, dtype=np.uint64) + base)
    return (bits >> np.uint64(11)).astype(np.float64) / float(1 << 53) * 2.0 - 1.0


def golden_input(manifest: dict[str, Any], seed: int = SEED) -> dict[str, Any]:
    """What the golden check feeds each graph (volumes come from the encoder).

    Parameters
    ----------
    manifest : dict
        The model's manifest (its ``inputs`` and ``schedule``).
    seed : int

    Returns
    -------
    dict
        ``points`` (1, P, 3 or 6), ``x_t`` (1, N, 4), ``t`` (1,), ``vertices`` (1, N, 3),
        ``valid`` (1, N).
    """
    inputs = manifest["inputs"]
    n_points, n_vertices = int(inputs["n_points"]), int(inputs["max_vertices"])
    u = hash_uniform(n_points * 2, seed, 0).reshape(n_points, 2)
    z, phi = u[:, 0], np.pi * u[:, 1]
    ring = np.sqrt(1.0 - z * z)
    direction = np.stack([ring * np.cos(phi), ring * np.sin(phi), z], axis=1)
    points = direction * np.array([0.8, 0.6, 0.5])
    if inputs.get("normals"):
        points = np.concatenate([points, direction], axis=1)
    timesteps = int(manifest["schedule"]["timesteps"])
    return {
        "points": points[None].astype(np.float32),
        "x_t": hash_uniform(n_vertices * 4, seed, 1).reshape(1, n_vertices, 4).astype(
            np.float32),
        "t": np.array([timesteps // 2], dtype=np.int64),
        "vertices": (0.8 * hash_uniform(n_vertices * 3, seed, 2)).reshape(
            1, n_vertices, 3).astype(np.float32),
        "valid": np.ones((1, n_vertices), dtype=bool),
    }


def golden_outputs(backend: OnnxBackend, manifest: dict[str, Any], seed: int = SEED
                   ) -> dict[str, dict[str, np.ndarray]]:
    """Every output of every graph for the golden input.

    Returns
    -------
    dict
        Graph name -> output name -> array.
    """
    feed = golden_input(manifest, seed)
    volumes = backend.encode(feed["points"])
    if "points" in manifest.get("graphs", {}).get("denoiser", {}).get("inputs", []):
        eps = backend.denoise(feed["x_t"], feed["t"], volumes, feed["points"])  # local points
    else:
        eps = backend.denoise(feed["x_t"], feed["t"], volumes)
    conn = backend.connect(feed["vertices"], feed["valid"], volumes)
    return {
        "encoder": dict(zip(volume_names(len(volumes)), volumes, strict=True)),
        "denoiser": {"eps": eps},
        "connectivity": {"x": conn.x, "root": conn.root, "prev": conn.prev, "next": conn.next,
                         "tau": np.array([conn.tau], dtype=np.float32)},
    }


def _sample_indices(size: int, seed: int) -> list[int]:
    """Up to :data:`SAMPLES` distinct flat indices into an output of ``size`` values."""
    if size <= SAMPLES:
        return list(range(size))
    picks = _splitmix64(np.arange(SAMPLES * 4, dtype=np.uint64) + np.uint64(seed + 1) *
                        np.uint64(1 << 40)) % np.uint64(size)
    return sorted(list(dict.fromkeys(int(i) for i in picks))[:SAMPLES])


def _stats(array: np.ndarray) -> tuple[float, float]:
    values = np.asarray(array, dtype=np.float64)
    return float(values.mean()), float(np.sqrt(np.mean(values * values)))


def _projections(flat: np.ndarray, seed: int) -> np.ndarray:
    """:data:`PROJECTIONS` dot products of ``flat`` with fixed directions in [-1, 1]^n,
    divided by sqrt(n)."""
    values = np.asarray(flat, dtype=np.float64)
    scale = 1.0 / np.sqrt(max(values.size, 1))
    return np.array([hash_uniform(values.size, seed, 100 + k) @ values * scale
                     for k in range(PROJECTIONS)])


def _short(value: float) -> float:
    """A float32 output value at the precision it has (9 significant digits)."""
    return float(f"{value:.9g}")


def golden_section(backend: OnnxBackend, manifest: dict[str, Any], *, seed: int = SEED,
                   tolerance: float = TOLERANCE) -> dict[str, Any]:
    """The manifest's ``golden`` section for a model's graphs as they are now.

    Parameters
    ----------
    backend : OnnxBackend
    manifest : dict
    seed : int
    tolerance : float
        Allowed deviation relative to each output's rms.

    Returns
    -------
    dict
    """
    import onnxruntime

    outputs = golden_outputs(backend, manifest, seed)
    graphs: dict[str, dict[str, Any]] = {}
    for graph, named in outputs.items():
        graphs[graph] = {}
        for name, array in named.items():
            flat = np.asarray(array).reshape(-1)
            indices = _sample_indices(flat.size, seed)
            mean, rms = _stats(flat)
            graphs[graph][name] = {
                "shape": list(np.shape(array)), "mean": _short(mean), "rms": _short(rms),
                "indices": indices, "values": [_short(float(flat[i])) for i in indices],
                "projections": [_short(p) for p in _projections(flat, seed)],
            }
    return {
        "about": "each graph's raw outputs for a fixed input (spacemesh.runtime.golden), "
                 "checked when the model loads",
        "seed": seed,
        "tolerance": tolerance,
        "onnxruntime": onnxruntime.__version__,
        "graphs": graphs,
    }


def golden_mismatches(backend: OnnxBackend, manifest: dict[str, Any]) -> list[str]:
    """Compare the graphs with the manifest's ``golden`` section.

    Parameters
    ----------
    backend : OnnxBackend
    manifest : dict
        With a ``golden`` section (see :func:`golden_section`).

    Returns
    -------
    list of str
        One sentence per output outside the tolerance, naming the graph, the output
        and by how much it moved (empty: the model passes).
    """
    section = manifest[SECTION]
    tolerance = float(section.get("tolerance", TOLERANCE))
    seed = int(section.get("seed", SEED))
    outputs = golden_outputs(backend, manifest, seed)
    problems = []
    for graph, recorded in section["graphs"].items():
        for name, golden in recorded.items():
            array = outputs.get(graph, {}).get(name)
            where = f"{graph} graph output {name!r}"
            if array is None:
                problems.append(f"{where} is missing")
                continue
            if list(np.shape(array)) != list(golden["shape"]):
                problems.append(f"{where} has shape {list(np.shape(array))}, "
                                f"recorded {golden['shape']}")
                continue
            flat = np.asarray(array, dtype=np.float64).reshape(-1)
            if not np.all(np.isfinite(flat)):
                problems.append(f"{where} has {int(np.sum(~np.isfinite(flat)))} non-finite "
                                "values")
                continue
            scale = max(float(golden["rms"]), _MIN_SCALE)
            mean, rms = _stats(flat)
            sampled = flat[np.asarray(golden["indices"], dtype=np.int64)]
            moved = np.abs(sampled - np.asarray(golden["values"], dtype=np.float64))
            worst = int(np.argmax(moved)) if moved.size else 0
            recorded = np.asarray(golden.get("projections", []), dtype=np.float64)
            projected = np.abs(_projections(flat, seed)[:recorded.size] - recorded)
            deviation = max(abs(mean - golden["mean"]), abs(rms - golden["rms"]),
                            float(moved.max(initial=0.0)),
                            float(projected.max(initial=0.0))) / scale
            if deviation > tolerance:
                at = ""
                if moved.size:
                    at = (f"; value {golden['indices'][worst]} is {sampled[worst]:.6g}, "
                          f"recorded {golden['values'][worst]:.6g}")
                problems.append(f"{where} moved by {deviation:.3g} of its rms (tolerance "
                                f"{tolerance:g}){at}")
    return problems
