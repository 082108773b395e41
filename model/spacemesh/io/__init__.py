"""Mesh and point-cloud files: every format in one place, dispatched by file type.

In the manner of ``trimesh.exchange``: one module per format (:mod:`.obj`, :mod:`.off`,
:mod:`.ply`, :mod:`.stl`, :mod:`.gltf`, and :mod:`.points` for point clouds), each
turning bytes into arrays and back; this module picks the format from the file
type, the file name's extension or, failing both, the content. Geometry code never
touches files.

Every malformed input raises :class:`~spacemesh.io.errors.MeshFormatError` (a
``ValueError``); an unknown file type raises its subclass
:class:`~spacemesh.io.errors.UnsupportedFormatError`.

Examples
--------
>>> from spacemesh.io import export_mesh, load_mesh
>>> mesh = load_mesh("part.off")  # doctest: +SKIP
>>> glb = export_mesh(mesh, "glb")  # doctest: +SKIP
>>> mesh = load_mesh(upload_bytes, file_type="upload.ply")  # doctest: +SKIP
"""

from spacemesh.io.errors import MeshFormatError, TooLargeError, UnsupportedFormatError
from spacemesh.io.limits import ReadLimits
from spacemesh.io.meshes import (
    SUPPORTED_MESH_READ,
    SUPPORTED_MESH_WRITE,
    MeshSource,
    export_mesh,
    load_mesh,
    normalize_file_type,
    read_source,
    resolve_file_type,
    save_mesh,
    sniff_file_type,
)
from spacemesh.io.points import SUPPORTED_POINTS_READ, load_points

__all__ = [
    "SUPPORTED_MESH_READ",
    "SUPPORTED_MESH_WRITE",
    "SUPPORTED_POINTS_READ",
    "MeshFormatError",
    "MeshSource",
    "ReadLimits",
    "TooLargeError",
    "UnsupportedFormatError",
    "export_mesh",
    "load_mesh",
    "load_points",
    "normalize_file_type",
    "read_source",
    "resolve_file_type",
    "save_mesh",
    "sniff_file_type",
]
