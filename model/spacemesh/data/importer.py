"""Import a folder of user meshes (ABC, ShapeNet, Thingi10K ...) into dataset shards.

Every OBJ, OFF, PLY, STL, GLB and glTF file under the folder is read with
:func:`spacemesh.io.load_mesh`, optionally decimated, and then goes through the
same canonical form, validation, point sampling and shard format as synthetic
shapes (:func:`spacemesh.data.pipeline.prepare_shape`). Files that cannot be
read or fail validation are skipped, each with its reasons, and listed in the
manifest's ``skipped``.

Three light clean-ups run before validation, because real files need them and
they move no surface by more than the validator's own tolerances:

- unreferenced vertices (common in OBJ files) are dropped;
- vertices closer than ``MIN_EDGE`` (1e-5 of the half extent) are welded, and the
  sliver faces between them dropped (CAD exports leave such near-duplicates);
- collinear "cap" triangles (zero area, as CAD exporters leave along straight
  edges) are removed by flipping the edge they lie on (:func:`flip_caps`); this
  changes connectivity only. (pymeshlab's ``meshing_remove_t_vertices`` in
  edge-flip mode was tried first and left folded edges on two of the real CAD meshes.)
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from spacemesh.data.pipeline import prepare_shape
from spacemesh.data.shards import SHARD_PATTERN, write_manifest, write_shard
from spacemesh.data.validate import MIN_ALTITUDE, MIN_EDGE
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels, decimate
from spacemesh.topology import check_topology

#: File name suffixes that are imported (case-insensitive).
MESH_SUFFIXES = (".obj", ".off", ".ply", ".stl", ".glb", ".gltf")
IMPORT_VERSION = "1.0.0"


def find_mesh_files(source: Path) -> list[Path]:
    """Mesh files under ``source`` (recursively), sorted by relative path.

    Parameters
    ----------
    source : Path

    Returns
    -------
    list of Path
    """
    return sorted(
        (p for p in Path(source).rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES),
        key=lambda p: p.relative_to(source).as_posix(),
    )


def weld_close_vertices(mesh: PolygonMesh, tolerance: float = MIN_EDGE) -> PolygonMesh:
    """Merge vertices closer than ``tolerance`` (relative to half the longest side).

    Faces left with fewer than three distinct corners (the slivers between merged
    vertices) are dropped; repeated consecutive corners are removed.

    Parameters
    ----------
    mesh : PolygonMesh
    tolerance : float

    Returns
    -------
    PolygonMesh
        ``mesh`` itself when no two vertices are that close.
    """
    from scipy.spatial import cKDTree

    scale = max(float(np.ptp(mesh.vertices, axis=0).max()) / 2, 1e-300)
    pairs = cKDTree(mesh.vertices).query_pairs(tolerance * scale, output_type="ndarray")
    if pairs.size == 0:
        return mesh
    n = mesh.n_vertices
    _, label = component_labels(n, pairs)  # (V,)
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    remap = first[label]  # every vertex -> the smallest index of its cluster
    faces = []
    for face in mesh.faces:
        ring = remap[face]
        ring = ring[ring != np.roll(ring, 1)] if len(ring) > 1 else ring
        if len(np.unique(ring)) >= 3:
            faces.append(ring)
    compact, _ = PolygonMesh.from_faces(mesh.vertices, faces).remove_unreferenced_vertices()
    return compact


def flip_caps(mesh: PolygonMesh, max_rounds: int = 8) -> PolygonMesh:
    """Flip the longest side of every numerically flat triangle (a "cap").

    A cap ``(a, b, c)`` has ``c`` (almost) on its side ``ab``. Flipping ``ab`` with
    the triangle ``(b, a, d)`` across it gives ``(a, d, c)`` and ``(d, b, c)``, which
    have area when ``d`` is off the line; geometry is unchanged. A flip that would
    duplicate an existing edge is skipped.

    Parameters
    ----------
    mesh : PolygonMesh
        Left unchanged unless it is a triangle mesh with caps.
    max_rounds : int
        Passes over the remaining caps (chains of collinear vertices need several).

    Returns
    -------
    PolygonMesh
    """
    if not mesh.is_triangle_mesh():
        return mesh
    v = mesh.vertices
    tri = mesh.face_indices.reshape(-1, 3).copy()
    scale = max(float(np.ptp(v, axis=0).max()) / 2, 1e-300)
    for _ in range(max_rounds):
        p = v[tri]  # (T, 3, 3)
        double_area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        sides = np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2)  # side k: corner k -> k + 1
        caps = np.flatnonzero(
            double_area / np.maximum(sides.max(axis=1), 1e-300) < MIN_ALTITUDE * scale
        )
        if caps.size == 0:
            break
        side_of: dict[tuple[int, int], int] = {}
        for face, (x, y, z) in enumerate(tri):
            side_of[(int(x), int(y))] = face
            side_of[(int(y), int(z))] = face
            side_of[(int(z), int(x))] = face
        edges = {(min(a, b), max(a, b)) for a, b in side_of}
        changed = False
        touched: set[int] = set()
        for f in caps:
            if f in touched:
                continue
            k = int(np.argmax(sides[f]))
            a, b, c = int(tri[f, k]), int(tri[f, (k + 1) % 3]), int(tri[f, (k + 2) % 3])
            g = side_of.get((b, a))
            if g is None or g in touched:
                continue
            d = int(tri[g].sum()) - a - b
            if d == c or (min(c, d), max(c, d)) in edges:
                continue
            tri[f] = (a, d, c)
            tri[g] = (d, b, c)
            edges.discard((min(a, b), max(a, b)))
            edges.add((min(c, d), max(c, d)))
            touched.update((int(f), int(g)))
            changed = True
        if not changed:
            break
    return PolygonMesh.from_faces(v, tri)


def _file_rng(relative: str, seed: int) -> np.random.Generator:
    digest = hashlib.sha256(relative.encode("utf-8")).digest()
    return np.random.default_rng([seed, int.from_bytes(digest[:8], "big")])


def import_file(
    path: Path, relative: str, *, decimate_to: int | None, points: int, seed: int,
    tolerate: frozenset[str] = frozenset(),
) -> tuple[dict | None, list[str]]:
    """Read, clean, (decimate,) validate and describe one file.

    Parameters
    ----------
    path : Path
    relative : str
        The file's path relative to the imported folder (its shape id).
    decimate_to : int, optional
        Decimate meshes with more vertices than this.
    points : int
    seed : int
    tolerate : frozenset of str
        Validator causes that do not reject a file (see
        :func:`spacemesh.data.pipeline.prepare_shape`).

    Returns
    -------
    shape : dict or None
    reasons : list of str
        Why the file was skipped (empty when imported).
    """
    from spacemesh.io import load_mesh
    from spacemesh.io.errors import MeshFormatError

    try:
        mesh = load_mesh(path)
    except MeshFormatError as error:
        return None, [f"unreadable: {error}"]
    except OSError as error:
        return None, [f"unreadable: {error.strerror or error}"]
    if mesh.n_faces == 0:
        return None, ["empty"]
    mesh, _ = mesh.remove_unreferenced_vertices()
    style = "import-qem" if decimate_to is not None else "import"
    rng = _file_rng(relative, seed)
    # The weld can pinch meshes whose twin vertices are apart, and a QEM result can
    # fold: try the cleaned mesh first, then without the weld, then smaller targets.
    targets = [None] if decimate_to is None else [decimate_to, decimate_to * 9 // 10]
    plans = [(weld, target) for target in targets for weld in (True, False)]
    causes: list[str] = []
    for weld, target in plans:
        try:
            cleaned = flip_caps(weld_close_vertices(mesh) if weld else mesh)
            if target is not None:
                cleaned = decimate(cleaned, target, genus=check_topology(cleaned).genus or 0)
        except Exception as error:  # pymeshlab raises its own types
            return None, [f"processing_error: {error}"]
        shape, attempt_causes = prepare_shape(
            cleaned,
            shape_id=relative,
            style=style,
            # numpy types seed_seq as ISeedSequence; a Generator's is a SeedSequence
            rng=np.random.default_rng(rng.bit_generator.seed_seq),  # type: ignore[arg-type]
            n_points=points,
            extra={"source_file": relative, "welded": weld},
            tolerate=tolerate,
        )
        if shape is not None:
            return shape, []
        if not causes or (not weld and target == targets[0]):  # report the file as it is
            causes = attempt_causes
    return None, causes


def import_folder(
    source: str | Path,
    out: str | Path,
    *,
    decimate_to: int | None = None,
    points: int = 2048,
    seed: int = 0,
    shard_size: int = 256,
    progress: bool = True,
    keep_self_intersecting: bool = False,
) -> dict:
    """Import every mesh file under ``source`` into a dataset in ``out``.

    Parameters
    ----------
    source : path
        Folder searched recursively for OBJ, OFF, PLY, STL, GLB and glTF files.
    out : path
        Dataset folder (created; shards already there are replaced).
    decimate_to : int, optional
        QEM-decimate meshes with more vertices than this.
    points : int
        Conditioning points per shape.
    seed : int
        Seeds the point sampling (per file, from the seed and the file's path).
    shard_size : int
        Files per shard.
    progress : bool
        Show a progress bar on stderr.
    keep_self_intersecting : bool
        Keep closed manifold meshes whose faces intersect (real collections have many;
        their records say ``"tolerated": ["self_intersection"]``).

    Returns
    -------
    dict
        The manifest; ``manifest["skipped"]`` lists ``{"file", "reasons"}``.
    """
    from tqdm import tqdm

    source, out = Path(source), Path(out)
    if not source.is_dir():
        raise FileNotFoundError(f"{source} is not a folder")
    files = find_mesh_files(source)
    if not files:
        raise FileNotFoundError(f"{source} has no {', '.join(MESH_SUFFIXES)} files")
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("shard-*.npz"):
        old.unlink()
    tolerate = frozenset({"self_intersection"} if keep_self_intersecting else ())
    names = []
    bar = tqdm(total=len(files), unit="file", disable=not progress)
    try:
        for k, first in enumerate(range(0, len(files), shard_size)):
            shapes, skipped = [], []
            for path in files[first : first + shard_size]:
                relative = path.relative_to(source).as_posix()
                shape, reasons = import_file(
                    path, relative, decimate_to=decimate_to, points=points, seed=seed,
                    tolerate=tolerate,
                )
                if shape is None:
                    skipped.append({"file": relative, "reasons": reasons})
                else:
                    shapes.append(shape)
                bar.update(1)
                bar.set_postfix(skipped=len(skipped), refresh=False)
            rejections: dict[str, int] = {}
            for entry in skipped:
                for reason in entry["reasons"]:
                    cause = reason.split(":", 1)[0]
                    rejections[cause] = rejections.get(cause, 0) + 1
            summary = {
                "shard": k,
                "first_index": first,
                "count": len(shapes),
                "attempts": len(shapes) + len(skipped),
                "rejections": dict(sorted(rejections.items())),
                "skipped": skipped,
            }
            name = SHARD_PATTERN.format(k)
            write_shard(out / name, shapes, summary)
            names.append(name)
    finally:
        bar.close()
    header = {
        "generator_version": IMPORT_VERSION,
        "source": "import",
        "source_dir": source.name,
        "seed": seed,
        "style": "import-qem" if decimate_to is not None else "import",
        "decimate_to": decimate_to,
        "tolerated": sorted(tolerate),
        "vertex_range": None,
        "points": points,
        "count_requested": len(files),
        "shard_size": shard_size,
    }
    return write_manifest(out, header, names)
