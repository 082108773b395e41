"""Deterministic dataset shards and the manifest that lists them.

A dataset is a folder with ``manifest.json`` and shards ``shard-00000.npz`` ...
Each shard is a zip written here with fixed timestamps and fixed compression, so
the same shapes give byte-identical files. Members (``N`` shapes, ``P`` points):

=====================  ===================  ===========================================
``vertices.npy``       (sum V, 3) float32   normalised, z-y-x sorted positions
``vertex_offsets.npy`` (N + 1,) int64       shape i owns ``vertices[o[i]:o[i+1]]``
``face_sizes.npy``     (sum F,) int32       sides of every face
``face_counts.npy``    (N + 1,) int64       shape i owns ``face_sizes[c[i]:c[i+1]]``
``face_indices.npy``   (sum S,) int32       corners, local to their shape
``corner_offsets.npy`` (N + 1,) int64       shape i owns ``face_indices[k[i]:k[i+1]]``
``points.npy``         (N, P, 3) float32    conditioning points on the surface
``normals.npy``        (N, P, 3) float32    unit normals at the points
``records.json``       list of N dicts      shape_id, index, split, genus, features ...
``shard.json``         dict                 shard summary (counts, rejections)
=====================  ===================  ===========================================

Shards can be opened with ``numpy.load`` for the arrays; :func:`open_dataset` is the
reader the training code uses.
"""

from __future__ import annotations

import hashlib
import io
import itertools
import json
import os
import zipfile
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, overload

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import FloatArray

MANIFEST = "manifest.json"
SHARD_PATTERN = "shard-{:05d}.npz"
FORMAT = "spacemesh-shards"
FORMAT_VERSION = 1
SPLITS = ("train", "val", "test")
_DATE_TIME = (1980, 1, 1, 0, 0, 0)  # the earliest a zip can hold: no wall-clock time
_COMPRESS_LEVEL = 6


@dataclass(frozen=True, eq=False)
class MeshRecord:
    """One stored shape.

    Attributes
    ----------
    shape_id : str
    mesh : PolygonMesh
        Normalised (longest axis spans [-1, 1]), vertices sorted z-y-x.
    points : (P, 3) float32
        Conditioning points sampled uniformly on the surface.
    normals : (P, 3) float32
        Unit surface normals at ``points``.
    split : str
        ``train``, ``val`` or ``test``.
    style : str
    genus : int
    features : dict
        e.g. ``{"concave_sharp": True, ...}``.
    tolerated : tuple of str
        Validator causes the import was told to tolerate and found (e.g.
        ``("self_intersection",)`` with ``--keep-self-intersecting``).
    """

    shape_id: str
    mesh: PolygonMesh
    points: FloatArray
    normals: FloatArray
    split: str
    style: str
    genus: int
    features: dict = field(default_factory=dict)
    tolerated: tuple[str, ...] = ()


def split_of(mesh: PolygonMesh, fractions: tuple[float, float] = (0.8, 0.9)) -> str:
    """Train/val/test split chosen by a hash of the shape's stored bytes (80/10/10).

    Identical shapes land in the same split, so duplicates cannot leak from train to test.

    Parameters
    ----------
    mesh : PolygonMesh
        The canonical (normalised, sorted, float32-rounded) mesh.
    fractions : (float, float)
        Cumulative fractions that end train and val.

    Returns
    -------
    str
    """
    digest = hashlib.sha256()
    digest.update(mesh.vertices.astype(np.float32).tobytes())
    digest.update(mesh.face_sizes.astype(np.int32).tobytes())
    digest.update(mesh.face_indices.astype(np.int32).tobytes())
    u = int.from_bytes(digest.digest()[:8], "big") / 2.0**64
    return "train" if u < fractions[0] else "val" if u < fractions[1] else "test"


# ---------------------------------------------------------------- writing
def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.ascontiguousarray(array), allow_pickle=False)
    return buffer.getvalue()


def _json_bytes(data) -> bytes:
    return json.dumps(data, sort_keys=True, indent=1).encode("utf-8")


def _zip_member(archive: zipfile.ZipFile, name: str, data: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=_DATE_TIME)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.create_system = 3
    info.external_attr = 0o644 << 16
    archive.writestr(info, data, compresslevel=_COMPRESS_LEVEL)


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it into place."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)


def shard_bytes(shapes: Sequence[dict], summary: dict) -> bytes:
    """Serialise shapes into the bytes of one shard.

    Parameters
    ----------
    shapes : sequence of dict
        Each with ``mesh`` (PolygonMesh), ``points``/``normals`` ((P, 3) float32)
        and ``record`` (JSON-ready dict with at least shape_id, split, genus,
        features, style).
    summary : dict
        Stored as ``shard.json``.

    Returns
    -------
    bytes
    """
    meshes = [s["mesh"] for s in shapes]
    vertex_counts = [m.n_vertices for m in meshes]
    face_counts = [m.n_faces for m in meshes]
    corner_counts = [m.face_indices.size for m in meshes]

    def offsets(counts: list[int]) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)

    def cat(arrays, dtype, shape) -> np.ndarray:
        return np.concatenate(arrays).astype(dtype) if arrays else np.zeros(shape, dtype)

    n_points = shapes[0]["points"].shape[0] if shapes else 0
    members = {
        "vertices.npy": cat([m.vertices for m in meshes], np.float32, (0, 3)),
        "vertex_offsets.npy": offsets(vertex_counts),
        "face_sizes.npy": cat([m.face_sizes for m in meshes], np.int32, (0,)),
        "face_counts.npy": offsets(face_counts),
        "face_indices.npy": cat([m.face_indices for m in meshes], np.int32, (0,)),
        "corner_offsets.npy": offsets(corner_counts),
        "points.npy": np.stack([s["points"] for s in shapes]).astype(np.float32)
        if shapes
        else np.zeros((0, n_points, 3), np.float32),
        "normals.npy": np.stack([s["normals"] for s in shapes]).astype(np.float32)
        if shapes
        else np.zeros((0, n_points, 3), np.float32),
    }
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, array in members.items():
            _zip_member(archive, name, _npy_bytes(array))
        _zip_member(archive, "records.json", _json_bytes([s["record"] for s in shapes]))
        _zip_member(archive, "shard.json", _json_bytes(summary))
    return buffer.getvalue()


def write_shard(path: Path, shapes: Sequence[dict], summary: dict) -> None:
    """Write one shard atomically (see :func:`shard_bytes`)."""
    write_atomic(Path(path), shard_bytes(shapes, summary))


def read_shard_summary(path: Path) -> dict:
    """The ``shard.json`` of a shard, plus its ``sha256`` and size in ``bytes``."""
    data = Path(path).read_bytes()
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        summary = json.loads(archive.read("shard.json"))
        records = json.loads(archive.read("records.json"))
    summary["sha256"] = hashlib.sha256(data).hexdigest()
    summary["bytes"] = len(data)
    summary["splits"] = {s: sum(r["split"] == s for r in records) for s in SPLITS}
    return summary


def write_manifest(directory: Path, header: dict, shard_files: Sequence[str]) -> dict:
    """Gather shard summaries into ``manifest.json`` (written atomically).

    Parameters
    ----------
    directory : Path
    header : dict
        Dataset-level fields (generator version, seed, style, vertex range ...).
    shard_files : sequence of str
        Shard file names, in index order.

    Returns
    -------
    dict
        The manifest.
    """
    directory = Path(directory)
    shards: list[dict[str, Any]] = []
    rejections: dict[str, int] = {}
    splits = dict.fromkeys(SPLITS, 0)
    stored = attempts = 0
    skipped: list = []
    failed: list = []
    for name in shard_files:
        summary = read_shard_summary(directory / name)
        shards.append(
            {
                "file": name,
                "first_index": summary.get("first_index", 0),
                "count": summary["count"],
                "sha256": summary["sha256"],
                "bytes": summary["bytes"],
            }
        )
        stored += summary["count"]
        attempts += summary.get("attempts", summary["count"])
        for cause, n in summary.get("rejections", {}).items():
            rejections[cause] = rejections.get(cause, 0) + n
        for split, n in summary["splits"].items():
            splits[split] += n
        skipped.extend(summary.get("skipped", []))
        failed.extend(summary.get("failed_indices", []))
    manifest = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        **header,
        "counts": {"stored": stored, "attempts": attempts, "shards": len(shards)},
        "splits": splits,
        "rejections": dict(sorted(rejections.items())),
        "skipped": skipped,
        "failed_indices": failed,
        "shards": shards,
    }
    write_atomic(directory / MANIFEST, json.dumps(manifest, sort_keys=True, indent=2).encode())
    return manifest


# ---------------------------------------------------------------- reading
class _Shard:
    """All arrays of one shard, loaded at once and sliced per shape."""

    def __init__(self, path: Path) -> None:
        with zipfile.ZipFile(path) as archive:
            self.arrays = {
                name[:-4]: np.lib.format.read_array(io.BytesIO(archive.read(name)))
                for name in archive.namelist()
                if name.endswith(".npy")
            }
            self.records = json.loads(archive.read("records.json"))

    def record(self, i: int) -> MeshRecord:
        a = self.arrays
        v0, v1 = a["vertex_offsets"][i : i + 2]
        f0, f1 = a["face_counts"][i : i + 2]
        c0, c1 = a["corner_offsets"][i : i + 2]
        sizes = a["face_sizes"][f0:f1].astype(np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        mesh = PolygonMesh(a["vertices"][v0:v1], a["face_indices"][c0:c1], offsets)
        meta = self.records[i]
        return MeshRecord(
            shape_id=meta["shape_id"],
            mesh=mesh,
            points=a["points"][i],
            normals=a["normals"][i],
            split=meta["split"],
            style=meta["style"],
            genus=int(meta["genus"]),
            features=dict(meta.get("features", {})),
            tolerated=tuple(meta.get("tolerated", ())),
        )


class Dataset(Sequence):
    """A sequence of :class:`MeshRecord` over the shards of one dataset folder.

    Shards are loaded whole on first use and kept (at most ``cache_shards`` of
    them, least recently used first out; all when None).
    """

    def __init__(self, directory: Path, split: str | None = None, cache_shards: int | None = None):
        self.directory = Path(directory)
        manifest_path = self.directory / MANIFEST
        if not manifest_path.is_file():
            raise FileNotFoundError(f"{self.directory} has no {MANIFEST}")
        self.manifest = json.loads(manifest_path.read_text())
        if self.manifest.get("format") != FORMAT:
            raise ValueError(f"{manifest_path} is not a {FORMAT} manifest")
        if split is not None and split not in SPLITS:
            raise ValueError(f"split must be one of {', '.join(SPLITS)}, not {split!r}")
        self.split = split
        self.cache_shards = cache_shards
        self._cache: OrderedDict[int, _Shard] = OrderedDict()
        self._files = [s["file"] for s in self.manifest["shards"]]
        index: list[tuple[int, int]] = []
        for k, name in enumerate(self._files):
            with zipfile.ZipFile(self.directory / name) as archive:
                records = json.loads(archive.read("records.json"))
            index.extend((k, i) for i, r in enumerate(records) if split in (None, r["split"]))
        self._index = index

    def _shard(self, k: int) -> _Shard:
        shard = self._cache.get(k)
        if shard is None:
            shard = _Shard(self.directory / self._files[k])
            self._cache[k] = shard
            if self.cache_shards is not None and len(self._cache) > self.cache_shards:
                self._cache.popitem(last=False)
        else:
            self._cache.move_to_end(k)
        return shard

    def __len__(self) -> int:
        return len(self._index)

    @overload
    def __getitem__(self, i: int) -> MeshRecord: ...

    @overload
    def __getitem__(self, i: slice) -> list[MeshRecord]: ...

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(i)
        k, local = self._index[i]
        return self._shard(k).record(local)

    def __repr__(self) -> str:
        return f"Dataset({str(self.directory)!r}, split={self.split!r}, n={len(self)})"


def open_dataset(
    directory: str | os.PathLike, split: str | None = None, cache_shards: int | None = None
) -> Dataset:
    """Open a dataset folder written by ``spacemesh data synth`` or ``data import``.

    Parameters
    ----------
    directory : path
        Folder with ``manifest.json`` and its shards.
    split : {"train", "val", "test"}, optional
        Only the shapes of this split (all when None).
    cache_shards : int, optional
        Keep at most this many loaded shards in memory (all when None).

    Returns
    -------
    Dataset
        A sequence of :class:`MeshRecord`.
    """
    return Dataset(Path(directory), split, cache_shards)


def first_records(
    directory: str | os.PathLike, split: str | None = None, *, max_vertices: int,
    limit: int,
) -> list[MeshRecord]:
    """The first ``limit`` shapes of a dataset (or split) with at most ``max_vertices``
    vertices, in storage order, reading no shard past the last one needed.

    Parameters
    ----------
    directory : path
    split : {"train", "val", "test"}, optional
    max_vertices : int
        A model's vertex tokens: larger shapes are skipped.
    limit : int

    Returns
    -------
    list of MeshRecord
    """
    fitting = (r for r in open_dataset(directory, split) if r.mesh.n_vertices <= max_vertices)
    return list(itertools.islice(fitting, limit))
