"""From any mesh to a stored shape: canonical form, validation, points, metadata.

Both the synthesiser and the importer go through :func:`prepare_shape`, so every
stored shape is normalised, sorted, rounded to float32 and validated in exactly
the form in which it is stored.
"""

from __future__ import annotations

import numpy as np

from spacemesh.data.features import shape_features
from spacemesh.data.normalize import canonical
from spacemesh.data.shards import split_of
from spacemesh.data.validate import validate_mesh
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import sample_surface
from spacemesh.topology import check_topology


def prepare_shape(
    mesh: PolygonMesh,
    *,
    shape_id: str,
    style: str,
    rng: np.random.Generator,
    n_points: int,
    vertex_range: tuple[int, int] | None = None,
    extra: dict | None = None,
    tolerate: frozenset[str] = frozenset(),
) -> tuple[dict | None, list[str]]:
    """Canonicalise, validate and describe one shape.

    Parameters
    ----------
    mesh : PolygonMesh
        Any closed mesh, in any frame.
    shape_id : str
    style : str
    rng : numpy.random.Generator
        Draws the conditioning points.
    n_points : int
        Conditioning points per shape.
    vertex_range : (int, int), optional
        Reject shapes with fewer or more vertices than this.
    extra : dict, optional
        More JSON-ready fields for the shape's record.
    tolerate : frozenset of str
        Validator causes that do not reject the shape (only ``self_intersection`` is
        meant for this); the record lists the ones found under ``tolerated``.

    Returns
    -------
    shape : dict or None
        ``mesh``, ``points``, ``normals`` and ``record``, as
        :func:`spacemesh.data.shards.shard_bytes` takes them; None when rejected.
    causes : list of str
        Rejection causes (empty when stored).
    """
    if mesh.n_faces == 0:
        return None, ["empty"]
    mesh, _ = mesh.remove_unreferenced_vertices()
    if vertex_range is not None:
        if mesh.n_vertices < vertex_range[0]:
            return None, ["too_few_vertices"]
        if mesh.n_vertices > vertex_range[1]:
            return None, ["too_many_vertices"]
    stored = canonical(mesh)
    found = validate_mesh(stored)
    causes = [cause for cause in found if cause not in tolerate]
    if causes:
        return None, causes
    tolerated = [cause for cause in found if cause in tolerate]
    points, normals = sample_surface(stored, n_points, rng)
    genus = check_topology(stored).genus
    record = {
        "shape_id": shape_id,
        "style": style,
        "split": split_of(stored),
        "genus": int(genus if genus is not None else -1),
        "n_vertices": stored.n_vertices,
        "n_faces": stored.n_faces,
        "features": shape_features(stored),
        **({"tolerated": tolerated} if tolerated else {}),
        **(extra or {}),
    }
    return {"mesh": stored, "points": points, "normals": normals, "record": record}, []
