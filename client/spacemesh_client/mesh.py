"""What a request returns: a :class:`Mesh` (the file the server sent, its vertices and
polygon faces, and the server's statistics) and its :class:`MeshStats`."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh_client import _formats
from spacemesh_client._formats import MEDIA_TYPES, WRITTEN, FormatError, read_mesh

#: Prefix of the statistics headers of ``POST /generate``.
HEADER_PREFIX = "x-spacemesh-"
#: Prefix of the fit report's headers.
FIT_PREFIX = HEADER_PREFIX + "fit-"


def _bool(text: str) -> bool:
    return text.strip().lower() == "true"


def _number(text: str) -> float | int | bool:
    """``"5"`` -> 5, ``"0.25"`` -> 0.25 (``nan`` and ``inf`` as floats), ``"true"`` ->
    True."""
    text = text.strip()
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return int(text) if text.lstrip("-").isdigit() else float(text)


def fit_from_headers(headers: Mapping[str, str]) -> dict[str, float | int] | None:
    """The fit report from the ``X-SpaceMesh-Fit-*`` headers (None without any):
    ``X-SpaceMesh-Fit-Points-To-Mesh-Mean`` -> ``points_to_mesh_mean``."""
    fit = {}
    for key, value in headers.items():
        key = key.lower()
        if key.startswith(FIT_PREFIX):
            try:
                fit[key[len(FIT_PREFIX):].replace("-", "_")] = _number(value)
            except ValueError:
                continue
    return fit or None


def sample_scores_from_text(text: str) -> list[tuple[int, float]]:
    """``5:0.0099,6:0.0098`` (``X-SpaceMesh-Sample-Scores``) -> [(5, 0.0099), (6, 0.0098)]."""
    scores = []
    for item in text.split(","):
        seed, _, score = item.partition(":")
        try:
            scores.append((int(seed), float(score)))
        except ValueError:
            continue
    return scores


@dataclass(frozen=True)
class MeshStats:
    """The server's checks of a mesh (``X-SpaceMesh-*`` headers, ``MeshStats`` in gRPC).

    Attributes
    ----------
    vertices, faces, edges : int
    face_degrees : dict of int to int
        Face size (3: triangle, 4: quad...) -> number of faces.
    manifold, closed, oriented : bool
    components : int
    genus : int
        Sum of the components' genera.
    fit : dict or None
        How well a generated mesh fits the uploaded points (None for a repair), by the
        names of the service's fit report: ``points_to_mesh_mean``, ``points_to_mesh_p95``,
        ``mesh_to_points_mean``, ``mesh_to_points_p95`` (input units), the same with
        ``_rel`` (fractions of the bounding-box diagonal), ``coverage`` (share of points
        within 1% of the diagonal from the mesh), ``components``,
        ``self_intersections`` (share of faces), ``diagonal``, ``n_points``, and the
        topology a user sees: ``pieces`` (connected through shared edges after welding
        equal positions), ``genus`` and ``boundary_loops``.
    """

    vertices: int
    faces: int
    edges: int
    face_degrees: dict[int, int]
    manifold: bool
    closed: bool
    oriented: bool
    components: int
    genus: int
    fit: dict[str, float | int] | None = None

    @classmethod
    def from_headers(cls, headers: Mapping[str, str]) -> MeshStats:
        """From the ``X-SpaceMesh-*`` response headers (case-insensitive mapping)."""
        h = {k.lower(): v for k, v in headers.items()}

        def get(name: str) -> str:
            return h.get(HEADER_PREFIX + name, "")

        degrees = {}
        for item in get("face-degrees").split(","):
            if ":" in item:
                size, count = item.split(":", 1)
                degrees[int(size)] = int(count)
        return cls(
            vertices=int(get("vertices") or 0), faces=int(get("faces") or 0),
            edges=int(get("edges") or 0), face_degrees=degrees,
            manifold=_bool(get("manifold")), closed=_bool(get("closed")),
            oriented=_bool(get("oriented")), components=int(get("components") or 0),
            genus=int(get("genus") or 0), fit=fit_from_headers(h),
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data (face degrees keyed by strings, as in the JSON format; no ``fit``
        when there is none)."""
        data = {**self.__dict__, "face_degrees": {str(k): v for k, v in
                                                  sorted(self.face_degrees.items())}}
        if self.fit is None:
            del data["fit"]
        return data


def repair_summary(data: Mapping[str, Any]) -> dict[str, Any]:
    """A repair's statistics as :attr:`Mesh.repair` holds them (face degrees keyed by
    ints, dicts sorted), from the ``X-SpaceMesh-Repair`` JSON or a gRPC ``RepairStats``."""
    out: dict[str, Any] = {}
    for key, value in data.items():
        if isinstance(value, Mapping):
            value = {int(k) if key == "new_face_degrees" else str(k): v
                     for k, v in value.items()}
            value = dict(sorted(value.items()))
        out[key] = value
    return out


@dataclass(frozen=True)
class Mesh:
    """A mesh from the service.

    ``data`` holds the file exactly as the server sent it; ``vertices`` and ``faces`` are
    read from it on first use. GLB and glTF hold triangles (the server triangulates
    them); ``json``, ``obj``, ``ply`` and ``off`` keep the polygons.

    Attributes
    ----------
    data : bytes
        The encoded mesh (the REST response body, or ``MeshReply.mesh``).
    format : str
        ``glb``, ``gltf``, ``obj``, ``ply``, ``off`` or ``json``.
    stats : MeshStats
    seed : int
        The seed used: the same input, seed, steps and model give the same mesh.
    steps : int
        Sampler steps used.
    sampler : str
    model : str
        ``name/version`` of the model.
    timings : dict of str to float
        Seconds per server stage (``queue``, ``encoder``, ``sampler``...).
    batch_size : int
        How many requests shared this one's inference batch.
    options : dict
        The resolved generate options the server reports, by name (``seed``, ``steps``,
        ``sampler``, ``start``, ``start_time``, ``samples``, ``raw``, and
        ``target_vertices`` when it was asked for; a repair: ``seed``, ``steps``,
        ``sampler``).
    sample_scores : list of (int, float)
        ``(seed, fit score)`` of every seed tried (``samples``; lower is better): the
        mesh is the lowest score's, :attr:`seed`.
    repair : dict or None
        What a repair did (None for a generated mesh): ``requested_faces``,
        ``region_faces`` (after growth), ``grown_faces``, ``removed_vertices``,
        ``boundary_vertices``, ``loops``, ``new_vertices``, ``new_faces``,
        ``new_face_degrees`` (size -> count), ``patch_faces``, ``patch_rings``,
        ``known_vertices``, ``tokens``, ``candidates``, ``fallback`` (``none``,
        ``removed-new-vertices`` or ``polygon``), ``fill``, ``inpaint``,
        ``flipped_orientation`` and ``welded_vertices`` (vertices merged away by
        ``repair(..., weld=True)``, 0 without); the same over REST and gRPC.
    points_reduced : dict or None
        ``{"read": N, "used": M}`` when the server reduced the uploaded points to the
        ``M`` the pipeline works on (a big binary cloud); None otherwise.
    """

    data: bytes = field(repr=False)
    format: str
    stats: MeshStats
    seed: int | None = None
    steps: int | None = None
    sampler: str = ""
    model: str = ""
    timings: dict[str, float] = field(default_factory=dict, repr=False)
    batch_size: int = 0
    repair: dict[str, Any] | None = field(default=None, repr=False)
    options: dict[str, Any] = field(default_factory=dict, repr=False)
    sample_scores: list[tuple[int, float]] = field(default_factory=list, repr=False)
    points_reduced: dict[str, int] | None = field(default=None, repr=False)

    @property
    def media_type(self) -> str:
        """The media type of :attr:`data`."""
        return MEDIA_TYPES.get(self.format, "application/octet-stream")

    @cached_property
    def _arrays(self) -> tuple[np.ndarray, list[np.ndarray]]:
        return read_mesh(self.data, self.format)

    @property
    def vertices(self) -> np.ndarray:
        """(V, 3) float64 vertex positions, in the input's frame."""
        return self._arrays[0]

    @property
    def faces(self) -> list[np.ndarray]:
        """Polygon faces: one int64 array of vertex indices per face, counter-clockwise
        seen from outside (triangles for ``glb``/``gltf``)."""
        return self._arrays[1]

    @property
    def face_sizes(self) -> np.ndarray:
        """(F,) number of vertices of each face."""
        return np.array([len(f) for f in self.faces], dtype=np.int64)

    def triangles(self) -> np.ndarray:
        """(T, 3) int64 triangles over :attr:`vertices`: each polygon fanned from its first
        corner whose fan adds no edge twice (orientation kept; exact for convex faces).

        Where no corner's fan is free (rare, folded meshes) the first corner's is used and
        an edge repeats; :meth:`triangulate` adds a centroid vertex there instead."""
        return _formats.triangulate(self.vertices, self.faces, centroids=False)[1]

    def triangulate(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and triangles that are a manifold wherever the polygon mesh is one.

        Returns
        -------
        vertices : (V + C, 3) float64
            :attr:`vertices`, then a centroid for each face none of whose fans was free.
        triangles : (T, 3) int64
        """
        return _formats.triangulate(self.vertices, self.faces)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the mesh; the file's extension picks the format.

        The same format as :attr:`format` writes :attr:`data` unchanged. Otherwise the
        client writes ``json``, ``obj``, ``off`` and ``ply`` (polygons kept) and ``glb``
        and ``gltf`` (triangulated) itself; any other format trimesh writes (``stl``...)
        goes through :meth:`to_trimesh`.

        Parameters
        ----------
        path : path

        Returns
        -------
        Path
        """
        path = Path(path)
        fmt = path.suffix.lower().lstrip(".")
        if fmt == self.format:
            path.write_bytes(self.data)
        elif fmt in WRITTEN:
            path.write_bytes(_formats.write_mesh(self.vertices, self.faces, fmt))
        elif not fmt:
            raise FormatError(f"{path}: give the file an extension (.{self.format}, .obj...)")
        else:
            self.to_trimesh().export(str(path))
        return path

    def to_trimesh(self) -> Any:
        """A ``trimesh.Trimesh`` (triangulated, not processed: vertex order kept).

        Needs the optional dependency: ``pip install spacemesh-client[trimesh]``.
        """
        try:
            import trimesh
        except ModuleNotFoundError:
            raise ModuleNotFoundError(
                "Mesh.to_trimesh needs trimesh: pip install 'spacemesh-client[trimesh]'"
            ) from None
        vertices, triangles = self.triangulate()
        return trimesh.Trimesh(vertices=vertices, faces=triangles, process=False)
