"""A toy dataset made in seconds with numpy and scipy only: convex hulls of random points
on ellipsoids (closed, outward triangle meshes), and a toy model trained and exported on
it through the real command line. Tests and smoke runs use them; real training uses
``spacemesh data synth``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spacemesh.data.normalize import canonical
from spacemesh.data.shards import SHARD_PATTERN, write_manifest, write_shard
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface


def hull_mesh(rng: np.random.Generator, n_vertices: int) -> PolygonMesh:
    """The convex hull of ``n_vertices`` random points on a random ellipsoid, outward.

    Parameters
    ----------
    rng : numpy.random.Generator
    n_vertices : int
        At least 4.

    Returns
    -------
    PolygonMesh
        A closed triangle mesh with every point as a vertex.
    """
    from scipy.spatial import ConvexHull

    while True:
        d = rng.standard_normal((n_vertices, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        v = d * rng.uniform(0.5, 1.0, size=3)
        hull = ConvexHull(v)
        if len(hull.vertices) == n_vertices:
            break
    tri = hull.simplices.copy()
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0
    tri[~outward] = tri[~outward][:, ::-1]
    return PolygonMesh.from_faces(v, tri)


def make_toy_dataset(
    directory: str | Path, *, count: int = 40, seed: int = 0,
    vertices: tuple[int, int] = (12, 40), points: int = 512,
) -> Path:
    """Write a dataset of convex hulls in the shard format of :mod:`spacemesh.data.shards`.

    Splits are assigned by index (8 train, 1 val, 1 test in every 10).

    Parameters
    ----------
    directory : path
    count : int
    seed : int
    vertices : (int, int)
        Inclusive vertex-count range.
    points : int
        Conditioning points per shape.

    Returns
    -------
    Path
        The dataset folder.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    shapes = []
    for i in range(count):
        mesh = canonical(hull_mesh(rng, int(rng.integers(vertices[0], vertices[1] + 1))))
        pts, nrm = sample_surface(mesh, points, rng)
        split = "val" if i % 10 == 8 else "test" if i % 10 == 9 else "train"
        record = {"shape_id": f"toy-{seed}-{i:05d}", "style": "hull", "split": split,
                  "genus": 0, "n_vertices": mesh.n_vertices, "n_faces": mesh.n_faces,
                  "features": {}}
        shapes.append({"mesh": mesh, "points": pts, "normals": nrm, "record": record})
    name = SHARD_PATTERN.format(0)
    write_shard(directory / name, shapes, {"count": count, "first_index": 0})
    header = {"source": "toy", "seed": seed, "style": "hull", "vertex_range": list(vertices),
              "points": points, "count_requested": count}
    write_manifest(directory, header, [name])
    return directory


def _run(command: list[str], env: dict[str, str]) -> None:
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"{' '.join(command[3:])} failed:\n{done.stderr[-4000:]}")


@dataclass(frozen=True)
class ToyModel:
    """A tiny model trained and exported through the command line (for tests and demos).

    Attributes
    ----------
    data : Path
        The toy dataset.
    run : Path
        The training run folder.
    repository : Path
        The exported version folder (``.../spacemesh-tiny/1``).
    seconds : float
        Wall time of training plus export.
    """

    data: Path
    run: Path
    repository: Path
    seconds: float


def build_toy_model(directory: str | Path, *, steps: int = 4, threads: int = 2) -> ToyModel:
    """Make a toy dataset, train ``tiny`` on it and export it, with the real CLI commands.

    Reuses a previous build in ``directory`` (a ``toy-model.json`` marker).

    Parameters
    ----------
    directory : path
    steps : int
        Diffusion steps of the training run.
    threads : int
        Torch threads of the subprocesses.

    Returns
    -------
    ToyModel
    """
    directory = Path(directory)
    marker = directory / "toy-model.json"
    if marker.is_file():
        info = json.loads(marker.read_text())
        return ToyModel(Path(info["data"]), Path(info["run"]), Path(info["repository"]),
                        info["seconds"])
    directory.mkdir(parents=True, exist_ok=True)
    data = make_toy_dataset(directory / "data", count=40, seed=0)
    run, models = directory / "run", directory / "models"
    cli = [sys.executable, "-c", "from spacemesh.cli import main; main()"]
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    start = time.perf_counter()
    _run([*cli, "train", "--config", "tiny", "--data", str(data), "--out", str(run),
          "--steps", str(steps), "--threads", str(threads), "--device", "cpu", "--no-progress"],
         env)
    _run([*cli, "export", str(run), "--out", str(models), "--threads", str(threads)], env)
    seconds = time.perf_counter() - start
    repository = models / "spacemesh-tiny" / "1"
    marker.write_text(json.dumps({"data": str(data), "run": str(run),
                                  "repository": str(repository), "seconds": seconds}))
    return ToyModel(data, run, repository, seconds)


def build_toy_model_once(directory: str | Path) -> ToyModel:
    """:func:`build_toy_model` under a file lock (``DIRECTORY.lock``), so that processes
    sharing ``directory`` (a test run's workers, the build ``scripts/test.sh`` starts in
    the background) make it once and the others wait for it, then find it built."""
    from filelock import FileLock

    directory = Path(directory)
    directory.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(str(directory) + ".lock"):
        return build_toy_model(directory)


if __name__ == "__main__":  # python -m spacemesh.train.toy DIRECTORY
    build_toy_model_once(sys.argv[1])

