"""The one validity check of the tests: a NON-EMPTY closed oriented manifold polygon mesh.

An empty mesh has no boundary edge, no non-manifold edge and no misoriented edge, so
``is_closed``, ``is_manifold`` and ``is_oriented`` all hold for it: a check built from
those passes when a generator quietly returns nothing. Every test that asserts that a
mesh is valid calls :func:`assert_valid_mesh`, which requires faces and vertices first.
"""

from __future__ import annotations

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.topology import TopologyReport, check_topology


def assert_valid_mesh(mesh: PolygonMesh, *, unreferenced: bool = False,
                      open_surface: bool = False) -> TopologyReport:
    """Assert that ``mesh`` has faces and vertices and is a closed oriented manifold
    (with ``open_surface``, boundary edges allowed: an oriented edge- and
    vertex-manifold, :meth:`TopologyReport.is_valid`).

    Parameters
    ----------
    mesh : PolygonMesh
    unreferenced : bool
        Allow vertices that no face uses (a decode's or a file's extra rows).
    open_surface : bool
        The mesh may have a boundary (``surface=open``).

    Returns
    -------
    TopologyReport
        The mesh's report, for further checks.
    """
    assert mesh.n_faces > 0, "the mesh is empty (no faces): nothing was validated"
    assert mesh.n_vertices > 0, "the mesh has no vertices"
    assert np.isfinite(mesh.vertices).all(), "the mesh has non-finite vertices"
    report = check_topology(mesh)
    assert report.is_valid(open_surface), report.defects(open_surface)
    assert int(mesh.face_sizes.min()) >= 3, "a face has fewer than three corners"
    if not unreferenced:
        assert report.n_unreferenced_vertices == 0, report.defects()
    return report


def assert_valid_faces(vertices, faces, *, unreferenced: bool = False) -> TopologyReport:
    """:func:`assert_valid_mesh` of a mesh given as vertex rows and a list of faces."""
    faces = [np.asarray(f, dtype=np.int64) for f in faces]
    assert len(faces) > 0, "the mesh is empty (no faces): nothing was validated"
    mesh = PolygonMesh.from_faces(np.asarray(vertices, dtype=np.float64), faces)
    return assert_valid_mesh(mesh, unreferenced=unreferenced)
