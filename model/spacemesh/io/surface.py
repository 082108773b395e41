"""The input of a generation: a point cloud, or points sampled on a mesh's surface.

A file whose reader finds faces (OBJ, OFF, PLY with a face element, STL, GLB/glTF) is a
*mesh*: its surface is sampled area-uniformly, with the normal of the face under each
point (:func:`spacemesh.primitives.sample_surface`), so a low-poly or partial mesh
gives as many points as the model reads, spread over its faces (a partial mesh is then
treated like a partial scan). Any other file, and a mesh format without faces (a PLY or
OBJ of vertices only), is a point cloud read by :func:`spacemesh.io.points.load_points`.
``spacemesh generate`` and the service's ``/generate`` both read their input here.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import BinaryIO, Literal

import numpy as np

from spacemesh.io.limits import ReadLimits
from spacemesh.typed import FloatArray

#: The formats whose readers may find faces.
SURFACE_FORMATS: tuple[str, ...] = ("obj", "off", "ply", "stl", "glb", "gltf")
#: Points sampled on a mesh when the caller names no count (the shipped model's encoder
#: count; the pipeline takes its model's count from them at random, which keeps them
#: area-uniform).
DEFAULT_SURFACE_POINTS = 2048
#: The suffix of :attr:`CloudInput.source` for a mesh's surface (``"obj-surface"``).
SURFACE_SUFFIX = "-surface"

InputKind = Literal["mesh", "points"]


@dataclass(frozen=True)
class CloudInput:
    """The points of a generation's input file.

    Attributes
    ----------
    points : (P, 3) float64
    normals : (P, 3) float64 or None
        A mesh's face normals; a point cloud's normals as stored (or None).
    kind : {"mesh", "points"}
        How the file was read.
    file_type : str
        The format read (``obj``, ``ply``, ``xyz``...).
    count : int, optional
        Points in the file when the cloud was reduced to ``points``
        (:func:`spacemesh.io.points.read_points`); None when ``points`` are all of them
        (or a mesh's samples).
    """

    points: FloatArray
    normals: FloatArray | None
    kind: InputKind
    file_type: str
    count: int | None = None

    @property
    def points_read(self) -> int:
        """Points in the file (samples of a mesh): ``count``, else ``len(points)``."""
        return len(self.points) if self.count is None else self.count

    @property
    def source(self) -> str:
        """``file_type``, with :data:`SURFACE_SUFFIX` for a mesh's surface."""
        return self.file_type + (SURFACE_SUFFIX if self.kind == "mesh" else "")


def input_kind(source: str) -> InputKind:
    """``mesh`` for a :attr:`CloudInput.source` of a sampled surface, else ``points``."""
    return "mesh" if source.endswith(SURFACE_SUFFIX) else "points"


def _has_area(mesh) -> bool:
    from spacemesh.primitives import triangles_of

    triangles, _ = triangles_of(mesh)
    if not len(triangles):
        return False
    v = mesh.vertices[triangles]
    return bool(np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
                > 0)


def load_cloud_input(
    path_or_bytes: str | os.PathLike[str] | bytes | BinaryIO,
    file_type: str | None = None,
    limits: ReadLimits | None = None,
    *,
    n_points: int = DEFAULT_SURFACE_POINTS,
    seed: int = 0,
    keep: int | None = None,
) -> CloudInput:
    """Read a generation's input: a mesh's surface sampled, or a point cloud.

    Parameters
    ----------
    path_or_bytes : path, bytes or binary file object
    file_type : str, optional
        Overrides the extension (as :func:`spacemesh.io.points.load_points`).
    limits : ReadLimits, optional
        A mesh is read within its vertex and face limits, a point cloud within its
        point limit.
    n_points : int
        Points sampled on a mesh's surface.
    seed : int
        Seed of the sampling (the same file gives the same points).
    keep : int, optional
        A point cloud of more points is reduced to this many
        (:func:`spacemesh.io.points.read_points`, its own fixed seed); None: all kept.

    Returns
    -------
    CloudInput

    Raises
    ------
    MeshFormatError, TooLargeError, UnsupportedFormatError
        As :func:`spacemesh.io.load_mesh` and :func:`spacemesh.io.points.load_points`.
    """
    from spacemesh.io import load_mesh, read_source, resolve_file_type
    from spacemesh.io.points import SUPPORTED_POINTS_READ, read_points
    from spacemesh.primitives import sample_surface

    if isinstance(path_or_bytes, (bytes, bytearray, memoryview)) or hasattr(
            path_or_bytes, "read"):
        data, extension, _ = read_source(path_or_bytes)
        source: str | os.PathLike[str] | bytes = data
    else:
        data, extension, _ = read_source(path_or_bytes)
        source = path_or_bytes  # a glTF path keeps its folder (external buffers)
    fmt = resolve_file_type(file_type, extension, data, SUPPORTED_POINTS_READ, "point cloud")
    # a PLY whose header declares no faces is a cloud: read once, as a cloud
    faceless_ply = fmt == "ply" and not _ply_has_faces(data)
    if fmt in SURFACE_FORMATS and not faceless_ply:
        mesh = load_mesh(source, file_type=fmt, limits=limits)
        if mesh.n_faces and _has_area(mesh):
            samples, sample_normals = sample_surface(mesh, int(n_points),
                                                     np.random.default_rng(seed))
            return CloudInput(samples.astype(np.float64), sample_normals.astype(np.float64),
                              "mesh", fmt)
    read = read_points(data, file_type=fmt, limits=limits, keep=keep)
    return CloudInput(read.points, read.normals, "points", fmt,
                      read.count if read.reduced else None)


def _ply_has_faces(data: bytes) -> bool:
    """Whether a PLY header declares faces (True when it cannot be read: the mesh
    reader then says why)."""
    from spacemesh.io.errors import MeshFormatError
    from spacemesh.io.ply import read_ply_header

    try:
        return read_ply_header(data).has_faces
    except MeshFormatError:
        return True


__all__ = ["DEFAULT_SURFACE_POINTS", "SURFACE_FORMATS", "CloudInput", "input_kind",
           "load_cloud_input"]
