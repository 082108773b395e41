"""Orienting the faces of a mesh consistently before an automatic region is planned
(:func:`orient_faces`): the minority orientation of each connected part reversed, a
closed part turned inside out reversed whole, a part that cannot be oriented (a Moebius
strip) refused.

numpy and scipy only.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import component_labels, fan_volumes
from spacemesh.repair.findings import MAX_REPORTED
from spacemesh.repair.halfedges import FaceSubset
from spacemesh.repair.region import NON_ORIENTABLE, RegionError
from spacemesh.typed import BoolArray, IntArray


def _edge_pairs(mesh: PolygonMesh) -> tuple[IntArray, IntArray, BoolArray]:
    """Faces on each side of every edge with exactly two sides, and whether the two
    sides run the same way (misoriented)."""
    sub = FaceSubset.of(mesh, np.arange(mesh.n_faces))
    idx = np.flatnonzero(sub.edge_count[sub.edge] == 2)
    order = idx[np.argsort(sub.edge[idx], kind="stable")]
    a, b = order[0::2], order[1::2]
    same = sub.halfedges[a, 0] == sub.halfedges[b, 0]
    return sub.face[a], sub.face[b], same


def reverse_faces(mesh: PolygonMesh, faces: BoolArray) -> PolygonMesh:
    """``mesh`` with the faces ``faces`` reversed (each keeps its first corner)."""
    if not faces.any():
        return mesh
    start = np.repeat(mesh.face_offsets[:-1], mesh.face_sizes)
    local = np.arange(mesh.face_indices.size) - start
    size = np.repeat(mesh.face_sizes, mesh.face_sizes)
    reversed_local = np.where(local == 0, 0, size - local)
    flip = faces[mesh.face_of_corner]
    source = np.where(flip, start + reversed_local, start + local)
    return PolygonMesh(mesh.vertices, mesh.face_indices[source], mesh.face_offsets)


def _signed_volumes(mesh: PolygonMesh, label: IntArray, n_labels: int) -> np.ndarray:
    """Signed volume of the faces of each label (each face fanned from its first corner)."""
    return np.bincount(label[mesh.face_of_corner], fan_volumes(mesh), minlength=n_labels)


def orient_faces(mesh: PolygonMesh) -> tuple[PolygonMesh, BoolArray]:
    """Orient the faces of every connected part consistently.

    Faces joined by an edge with exactly two sides must traverse it in opposite
    directions. Within each part the smaller of the two consistent classes is reversed;
    a closed part (no open edge) with a negative enclosed volume (inside out) is then
    reversed whole.

    Parameters
    ----------
    mesh : PolygonMesh

    Returns
    -------
    oriented : PolygonMesh
    reversed : (F,) bool
        Faces reversed.

    Raises
    ------
    RegionError
        ``non-orientable`` (details: ``faces``, the first faces of the part) when a part
        has no consistent orientation.
    """
    n_faces = mesh.n_faces
    fa, fb, same = _edge_pairs(mesh)
    # nodes f (kept) and f + F (reversed): a same-way edge joins f with g + F
    rows = np.concatenate([fa, fa + n_faces])
    cols = np.concatenate([np.where(same, fb + n_faces, fb), np.where(same, fb, fb + n_faces)])
    _, label = component_labels(2 * n_faces, np.stack([rows, cols], axis=1))  # (2F,)
    keep, flip = label[:n_faces], label[n_faces:]
    bad = np.flatnonzero(keep == flip)
    if bad.size:
        raise RegionError(
            NON_ORIENTABLE, f"the mesh is not orientable (like a Moebius strip): its faces "
            f"around face {int(bad[0])} cannot all face the same way, so no closed oriented "
            "surface can be made from them", {"faces": [int(f) for f in bad[:MAX_REPORTED]]})
    # each part's two classes are labels keep[f] and flip[f]; reverse the smaller one
    part = np.minimum(keep, flip)
    in_keep = np.bincount(part, keep == part, minlength=label.max() + 1)
    total = np.bincount(part, minlength=label.max() + 1)
    reverse = np.where(in_keep[part] * 2 >= total[part], keep != part, keep == part)
    oriented = reverse_faces(mesh, reverse)
    sub = FaceSubset.of(oriented, np.arange(n_faces))
    open_part = np.zeros(label.max() + 1, dtype=bool)
    open_part[part[sub.face[sub.edge_count[sub.edge] == 1]]] = True
    inside_out = (_signed_volumes(oriented, part, label.max() + 1) < 0) & ~open_part
    whole = inside_out[part]
    if whole.any():
        oriented = reverse_faces(oriented, whole)
        reverse ^= whole
    return oriented, reverse
