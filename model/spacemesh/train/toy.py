"""A toy dataset made in seconds with numpy and scipy only: convex hulls of random points
on ellipsoids (closed, outward triangle meshes). Tests and smoke runs use it; real
training uses ``spacemesh data synth``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spacemesh.data.normalize import canonical
from spacemesh.data.sampling import sample_surface
from spacemesh.data.shards import SHARD_PATTERN, write_manifest, write_shard
from spacemesh.mesh import PolygonMesh


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
