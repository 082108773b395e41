"""What a caller may pass, turned into what a transport sends.

``generate`` takes a point cloud as an array, a file path, file bytes or a trimesh
object; ``repair`` takes a mesh as a path, a :class:`~spacemesh_client.mesh.Mesh` or a
trimesh object, and a region as its JSON form or a list of face indices.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh_client._formats import write_mesh
from spacemesh_client.mesh import Mesh

#: A point cloud: (P, 3) numbers, a path, file bytes or a trimesh object with ``vertices``.
PointsLike = Any
#: A mesh: a path, a :class:`Mesh` or a trimesh object.
MeshLike = Any
#: A repair region: ``{"faces": [...]}``, ``{"vertices": [...]}``,
#: ``{"sphere": {"center": [x, y, z], "radius": r}}``, ``{"box": {"min": [...], "max": [...]}}``
#: or a list of face indices.
RegionLike = Any


@dataclass(frozen=True)
class Upload:
    """A file as uploaded: its bytes and name (the extension picks the format)."""

    data: bytes
    filename: str


@dataclass(frozen=True)
class Arrays:
    """Points (and normals) as numbers."""

    points: np.ndarray  # (P, 3) float64
    normals: np.ndarray | None  # (P, 3) float64


def _read_path(path: str | os.PathLike[str]) -> Upload:
    path = Path(path)
    try:
        return Upload(path.read_bytes(), path.name)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise IsADirectoryError(f"{path}: is a directory, not a file") from None


def points_input(source: PointsLike, normals: Any = None,
                 filename: str | None = None) -> Upload | Arrays:
    """The request input for a point cloud.

    Parameters
    ----------
    source : array-like, path, bytes or trimesh object
        (P, 3) numbers (or (P, 6): points then normals); a file the server reads
        (PLY, XYZ/PTS/TXT, NPY/NPZ, LAS/LAZ, OBJ, OFF, STL, GLB, glTF); its bytes; or an object
        with ``vertices`` (``trimesh.PointCloud``, ``trimesh.Trimesh``).
    normals : array-like, optional
        (P, 3) normals, with numbers or a trimesh object only.
    filename : str, optional
        The name sent with bytes (its extension picks the format; else the server
        sniffs the content).

    Returns
    -------
    Upload or Arrays
    """
    if isinstance(source, (str, os.PathLike)):
        if normals is not None:
            raise ValueError("normals go with points given as numbers; a file carries its own")
        return _read_path(source)
    if isinstance(source, (bytes, bytearray, memoryview)):
        if normals is not None:
            raise ValueError("normals go with points given as numbers; a file carries its own")
        return Upload(bytes(source), filename or "points")
    if hasattr(source, "vertices") and not isinstance(source, np.ndarray):
        source = source.vertices
    try:
        points = np.asarray(source, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("points must be (P, 3) numbers, a path, bytes or a trimesh object, "
                        f"not {type(source).__name__}") from None
    if points.ndim == 2 and points.shape[1] == 6 and normals is None:
        points, normals = points[:, :3], points[:, 3:]
    n = None if normals is None else np.asarray(normals, dtype=np.float64)
    return Arrays(points, n)


def mesh_input(mesh: MeshLike, filename: str | None = None) -> Upload:
    """The upload of a mesh to repair.

    Parameters
    ----------
    mesh : path, bytes, Mesh or trimesh object
    filename : str, optional
        The name sent with bytes.

    Returns
    -------
    Upload
    """
    if isinstance(mesh, (str, os.PathLike)):
        return _read_path(mesh)
    if isinstance(mesh, (bytes, bytearray, memoryview)):
        return Upload(bytes(mesh), filename or "mesh")
    if isinstance(mesh, Mesh):
        if mesh.format == "json":  # the service's own format, which it does not read back
            return Upload(write_mesh(mesh.vertices, mesh.faces, "ply"), "mesh.ply")
        return Upload(mesh.data, f"mesh.{mesh.format}")
    if hasattr(mesh, "export") and hasattr(mesh, "faces"):  # trimesh.Trimesh
        return Upload(bytes(mesh.export(file_type="ply")), "mesh.ply")
    raise TypeError(f"cannot send a {type(mesh).__name__} as a mesh; give a path, a Mesh "
                    "or a trimesh.Trimesh")


def region_input(region: RegionLike, auto: str | None = None) -> dict[str, Any]:
    """The JSON form of a repair region (a list of ints means face indices), or the
    automatic region ``{"auto": auto}`` (``holes``, ``defects`` or ``all``)."""
    if auto is not None:
        if region is not None:
            raise TypeError("give either region or auto, not both")
        return {"auto": str(auto)}
    if region is None:
        raise TypeError("give a region (or auto='holes', 'defects' or 'all')")
    if isinstance(region, Mapping):
        return {k: _plain(v) for k, v in region.items()}
    if isinstance(region, (str, bytes)):
        raise TypeError("region must be a dict such as {'faces': [1, 2]} or a list of faces")
    return {"faces": [int(i) for i in np.asarray(region).reshape(-1).tolist()]}


def _plain(value: Any) -> Any:
    """numpy arrays and scalars -> lists and numbers (JSON-ready)."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value
