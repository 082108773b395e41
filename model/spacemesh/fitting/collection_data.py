"""The meshes of a collection fit (paper Sec. 4.2): read, check, normalise, sort z-y-x.

Each mesh is centred on its bounding box, scaled so that its longest axis spans
[-1, 1] and its vertices sorted z-y-x (PolyGen's order, as the paper's Supplement
does); vertex slot ``i`` of the decoder is the ``i``-th vertex in that order, so no
matching is needed between predicted and true vertices.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spacemesh.connectivity import Connectivity
from spacemesh.data.normalize import sort_zyx
from spacemesh.encode import encode_connectivity, require_closed_manifold
from spacemesh.errors import SpaceMeshError
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import normalize
from spacemesh.typed import FloatArray

#: The paper pads every mesh to N = 2000 vertex tokens.
MAX_VERTICES = 2000


@dataclass(frozen=True)
class CollectionMesh:
    """One mesh of a collection, in the decoder's frame.

    Attributes
    ----------
    name : str
        The file name (the decoded file's stem).
    mesh : PolygonMesh
        Normalised (longest axis spans [-1, 1]) and sorted z-y-x.
    connectivity : Connectivity
        Its edges and cyclic neighbour orders.
    centre : (3,) float
    scale : float
        ``original = mesh.vertices * scale + centre``.
    digest : str
        SHA-256 of the normalised vertices and faces (resume checks it).
    """

    name: str
    mesh: PolygonMesh
    connectivity: Connectivity
    centre: FloatArray
    scale: float
    digest: str


def prepare_mesh(mesh: PolygonMesh, name: str, max_vertices: int = MAX_VERTICES) -> CollectionMesh:
    """Check, normalise and sort one mesh.

    Parameters
    ----------
    mesh : PolygonMesh
        A closed oriented manifold polygon mesh (unreferenced vertices are dropped).
    name : str
    max_vertices : int

    Returns
    -------
    CollectionMesh

    Raises
    ------
    SpaceMeshError
        Not a closed oriented manifold, or more than ``max_vertices`` vertices.
    """
    require_closed_manifold(mesh)
    mesh, _ = mesh.remove_unreferenced_vertices()
    if mesh.n_vertices > max_vertices:
        raise SpaceMeshError(
            f"{mesh.n_vertices} vertices, more than the collection's limit of {max_vertices}"
        )
    normalised, centre, scale = normalize(mesh)
    normalised = sort_zyx(normalised)
    digest = hashlib.sha256(
        normalised.vertices.astype(np.float64).tobytes() + normalised.face_indices.tobytes()
    ).hexdigest()
    return CollectionMesh(
        name=name,
        mesh=normalised,
        connectivity=encode_connectivity(normalised, check=False),
        centre=centre,
        scale=scale,
        digest=digest,
    )


def load_collection(
    paths: Sequence[str | Path], max_vertices: int = MAX_VERTICES
) -> list[CollectionMesh]:
    """Read and prepare mesh files (the readers of ``spacemesh fit``).

    Raises
    ------
    SpaceMeshError
        The first unusable file, named in the message.
    """
    from spacemesh.io import load_mesh
    from spacemesh.io.errors import MeshFormatError

    meshes = []
    for path in map(Path, paths):
        if not path.is_file():
            raise SpaceMeshError(f"{path}: no such file")
        try:
            meshes.append(prepare_mesh(load_mesh(path), path.name, max_vertices))
        except (MeshFormatError, SpaceMeshError) as error:
            raise SpaceMeshError(f"{path}: {error}") from error
    names = [m.name for m in meshes]
    if len(set(names)) != len(names):
        raise SpaceMeshError("two meshes have the same file name; decoded files would clash")
    return meshes
