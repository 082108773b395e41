"""How well do bare points tell a closed surface's genus? (issue 47, clause 3)

For each real mesh of a split, 2,048 points are sampled as in the evaluation. The points
are voxelised at a few multiples of their spacing, the occupied voxels dilated into a
watertight shell, the outside flood-filled, and the genus of the solid read from its
Euler characteristic (a solid without cavities: genus = pieces - chi). The estimate is
compared with the mesh's own genus.

With ``--balls``, the solid is instead the union of balls around the points (voxels of a
third of the median radius): a radius of ``scale`` median spacings, or, with
``--neighbour K``, ``scale`` times each point's distance to its K-th neighbour (a radius
that grows where the random sampling leaves gaps). ``--data DIR`` reads a synthetic
dataset (``spacemesh data synth``; its first ``--limit`` shapes) instead of a split.

Usage::

    python experiments/genus_from_points.py --split dev [--scales 1.5,2,3]
    python experiments/genus_from_points.py --data data/qemflip-tune-s3 --balls \
        --scales 3,4 [--neighbour 8]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_real_meshes import CATEGORIES, split_meshes, split_parser


def main() -> int:
    parser = split_parser(__doc__)
    parser.add_argument("--scales", default="1.5,2,3")
    parser.add_argument("--points", type=int, default=2048)
    parser.add_argument("--data", default=None, help="a synthetic dataset instead")
    parser.add_argument("--limit", type=int, default=50)
    parser.add_argument("--balls", action="store_true", help="a union of balls")
    parser.add_argument("--neighbour", type=int, default=0,
                        help="with --balls: radii from each point's K-th neighbour")
    args = parser.parse_args()
    from spacemesh.evaluate.runner import load_shapes, mesh_shapes
    from spacemesh.geometry.pieces import point_pieces
    from spacemesh.topology import check_topology

    if args.data is not None:
        shapes = load_shapes(args.data, split="all", limit=args.limit)
    else:
        paths, categories = split_meshes(args.meshes, args.split, set(CATEGORIES))
        shapes = mesh_shapes(paths, categories=categories, points=args.points, seed=0)
    scales = [float(s) for s in args.scales.split(",")]
    right = {s: 0 for s in scales}
    right_pieces = 0
    agreed = agreed_right = 0
    print("shape | genus | pieces | " + " | ".join(f"x{s}" for s in scales) + " | agreed")
    for shape in shapes:
        report = check_topology(shape.mesh)
        truth = report.genus
        estimates = [ball_genus(shape.points, scale=s, neighbour=args.neighbour)
                     if args.balls else point_genus(shape.points, scale=s) for s in scales]
        pieces = point_pieces(shape.points)
        right_pieces += pieces == report.n_components
        for s, e in zip(scales, estimates, strict=True):
            right[s] += e == truth
        stable = len(set(estimates)) == 1
        agreed += stable
        agreed_right += stable and estimates[0] == truth
        print(f"{shape.shape_id[:40]} | {truth} | {report.n_components}/{pieces} | "
              + " | ".join(str(e) for e in estimates) + f" | {stable}")
    n = len(shapes)
    print(f"\n{n} meshes; pieces right {right_pieces}/{n}")
    for s in scales:
        print(f"scale {s}: genus right {right[s]}/{n}")
    print(f"all scales agree on {agreed}/{n}, of which right {agreed_right}")
    return 0


def point_genus(points: np.ndarray, *, scale: float = 2.0, dilation: int = 1) -> int:
    """The genus of the solid the points bound, voxelised at ``scale`` spacings.

    Parameters
    ----------
    points : (P, 3) float
    scale : float
        Voxel size in median nearest-neighbour spacings.
    dilation : int
        Voxel layers added around the occupied ones to close the shell.

    Returns
    -------
    int
        Summed genus of the solid's pieces (pieces minus its Euler characteristic).
    """
    from scipy import ndimage
    from scipy.spatial import cKDTree

    gaps, _ = cKDTree(points).query(points, k=2)
    size = scale * float(np.median(gaps[:, 1]))
    pad = dilation + 2
    cells = np.floor((points - points.min(axis=0)) / size).astype(np.int64) + pad  # (P, 3)
    occupied = np.zeros(cells.max(axis=0) + pad + 1, dtype=bool)
    occupied[tuple(cells.T)] = True
    cube = np.ones((3, 3, 3), dtype=bool)
    if dilation:
        occupied = ndimage.binary_dilation(occupied, structure=cube, iterations=dilation)
    empty_label, _ = ndimage.label(~occupied)  # 6-connected empty space
    solid = empty_label != empty_label[0, 0, 0]
    n_pieces = ndimage.label(solid, structure=cube)[1]
    return n_pieces - euler_characteristic(solid)


def ball_genus(points: np.ndarray, *, scale: float = 3.0, neighbour: int = 0) -> int:
    """The genus of the union of balls around the points, its cavities filled.

    Parameters
    ----------
    points : (P, 3) float
    scale : float
        Radius in median nearest-neighbour spacings, or with ``neighbour`` in each
        point's distance to its ``neighbour``-th nearest point.
    neighbour : int
        0: one radius for every point.

    Returns
    -------
    int
        Pieces minus the Euler characteristic of the voxelised union (a third of the
        median radius per voxel).
    """
    from scipy import ndimage
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    gaps, _ = tree.query(points, k=max(neighbour, 1) + 1)  # (P, K + 1)
    radius = scale * (gaps[:, neighbour] if neighbour else np.full(len(points),
                                                                  np.median(gaps[:, 1])))
    size = float(np.median(radius)) / 3.0
    origin = points.min(axis=0) - radius.max() - 2 * size
    shape = np.ceil((points.max(axis=0) + radius.max() + 2 * size - origin) / size)
    grid = np.stack(np.meshgrid(*[np.arange(int(k)) for k in shape], indexing="ij"), -1)
    centres = origin + (grid.reshape(-1, 3) + 0.5) * size  # (C, 3)
    solid = np.zeros(len(centres), dtype=bool)
    for near in cKDTree(centres).query_ball_point(points, radius):
        solid[near] = True
    solid = ndimage.binary_fill_holes(solid.reshape(grid.shape[:3]))
    n_pieces = ndimage.label(solid, structure=np.ones((3, 3, 3), dtype=bool))[1]
    return n_pieces - euler_characteristic(solid)


def euler_characteristic(solid: np.ndarray) -> int:
    """The Euler characteristic of the union of closed unit cubes at ``solid``'s cells."""
    s = np.pad(solid, 1)
    cubes = int(s.sum())
    faces = sum(int((s | np.roll(s, 1, axis=a)).sum()) for a in range(3))
    edges = 0
    for a in range(3):
        b, c = [x for x in range(3) if x != a]
        t = s | np.roll(s, 1, axis=b)
        edges += int((t | np.roll(t, 1, axis=c)).sum())
    t = s | np.roll(s, 1, axis=0)
    t = t | np.roll(t, 1, axis=1)
    vertices = int((t | np.roll(t, 1, axis=2)).sum())
    return vertices - edges + faces - cubes


if __name__ == "__main__":
    raise SystemExit(main())
