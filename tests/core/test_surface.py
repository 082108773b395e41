"""Open surfaces (``surface=open``): a closed mesh trimmed to its points.

The guarantee is the decode's, with rims: whatever faces the points support, the
trimmed mesh is an oriented edge- and vertex-manifold (no pinched vertex) whose faces
are faces of the closed mesh. Hypothesis draws the support itself (any subset of faces,
on a sphere, a torus of quads and a thin slab) and the property holds for every draw;
the unit tests check what the points decide: a complete cloud stays closed, a one-sided
one opens along its rim and faces the side it was seen from.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spacemesh.examples import icosphere, torus_grid
from spacemesh.geometry.orientation import oriented_normals
from spacemesh.geometry.surface import (
    AUTO_OPEN_SHARE,
    SurfaceSupport,
    decide_open,
    face_support,
    open_surface,
    shape_surface,
)
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import flip_faces, sample_surface
from spacemesh.topology import check_topology, count_vertex_fans
from tests.validity import assert_valid_mesh


def slab() -> PolygonMesh:
    """A sphere flattened to a thin disk (2 x 2 x 0.04), oriented outward: the closed
    shell a one-sided scan of a plate decodes to, two layers close together."""
    sphere = icosphere(2)
    return sphere.with_vertices(sphere.vertices * [1.0, 1.0, 0.02])


MESHES = {"sphere": icosphere(2), "torus": torus_grid(10, 6), "slab": slab()}


def support_of(mesh: PolygonMesh, mask: np.ndarray) -> SurfaceSupport:
    return SurfaceSupport(mask, float(1.0 - mask.mean()))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(name=st.sampled_from(sorted(MESHES)), data=st.data())
def test_any_support_trims_to_an_oriented_manifold_with_rims(name, data):
    mesh = MESHES[name]
    mask = np.asarray(data.draw(st.lists(st.booleans(), min_size=mesh.n_faces,
                                         max_size=mesh.n_faces)), dtype=bool)
    trimmed, stats = open_surface(mesh, support_of(mesh, mask))
    report = assert_valid_mesh(trimmed, open_surface=True)
    assert report.n_nonmanifold_vertices == 0 and report.is_oriented
    # its faces are faces of the closed mesh, up to orientation (none made, none moved)
    closed_faces = {frozenset(map(tuple, mesh.vertices[f].round(9))) for f in mesh.faces}
    assert all(frozenset(map(tuple, trimmed.vertices[f].round(9))) in closed_faces
               for f in trimmed.faces)
    if mask.all() or not mask.any():
        assert trimmed is mesh
    else:
        assert trimmed.n_faces == mesh.n_faces - stats["faces_trimmed"]


def test_a_pinched_support_loses_its_smaller_fan():
    mesh = icosphere(1)
    fans = count_vertex_fans  # two face groups meeting at vertex 0 only
    around = [f for f, face in enumerate(mesh.faces) if 0 in face]
    mask = np.zeros(mesh.n_faces, dtype=bool)
    mask[around[0]] = True
    # every face far from face around[0] but touching vertex 0 through another corner
    far = [f for f in around if not set(mesh.faces[f]) & (set(mesh.faces[around[0]]) - {0})]
    mask[far[0]] = True
    keep = mask.copy()
    trimmed, stats = open_surface(mesh, support_of(mesh, keep))
    assert (fans(trimmed) <= 1).all()
    assert stats["faces_unpinched"] >= 1


@pytest.fixture(scope="module")
def sphere_points():
    mesh = icosphere(3)
    points, normals = sample_surface(mesh, 3000, np.random.default_rng(0))
    return mesh, points, normals


def test_a_complete_cloud_supports_its_whole_closed_mesh(sphere_points):
    _, points, _ = sphere_points
    support = face_support(icosphere(2), points)
    assert support.unsupported_area == 0.0 and support.supported.all()
    assert not decide_open("auto", support) and decide_open("open", support)
    kept, facts, stats = shape_surface(icosphere(2), points, None, "auto")
    assert kept.n_faces == icosphere(2).n_faces and not facts.open and stats == {}


@pytest.mark.parametrize("inward", [False, True])
def test_a_one_sided_cloud_opens_along_its_rim_facing_where_it_was_seen(sphere_points,
                                                                          inward):
    _, points, normals = sphere_points
    seen = normals[:, 2] > 0.0  # a scan from +z
    closed = icosphere(2)
    closed = flip_faces(closed) if inward else closed  # orientation comes from the points
    kept, facts, stats = shape_surface(closed, points[seen], None, "auto")
    assert facts.open and facts.unsupported_area >= AUTO_OPEN_SHARE
    report = assert_valid_mesh(kept, open_surface=True)
    assert report.n_boundary_edges > 0
    centroids = np.array([kept.vertices[f].mean(axis=0) for f in kept.faces])
    assert centroids[:, 2].min() > -0.3  # the far side went
    # the kept cap faces +z, the side its points were seen from
    assert (kept.face_normals()[:, 2] * (centroids[:, 2] > 0.3)).sum() > 0
    assert stats["pieces_flipped"] == int(inward)
    closed_only, facts, _ = shape_surface(closed, points[seen], None, "closed")
    assert closed_only is closed and not facts.open


def test_the_uploads_normals_choose_the_side_of_a_thin_slab():
    mesh = slab()
    rng = np.random.default_rng(1)
    xy = rng.uniform(-0.7, 0.7, (800, 2))
    top = np.column_stack([xy, 0.02 * np.sqrt(np.clip(1 - (xy ** 2).sum(axis=1), 0, 1))])
    up = np.tile([0.0, 0.0, 1.0], (800, 1))
    for normals, sign in ((up, 1.0), (-up, -1.0)):
        support = face_support(mesh, top, normals)
        kept, _ = open_surface(mesh, support)
        assert_valid_mesh(kept, open_surface=True)
        assert (kept.face_normals()[:, 2] * sign > 0.9).mean() > 0.9


def test_an_unknown_surface_is_refused():
    with pytest.raises(ValueError, match="surface"):
        decide_open("half", SurfaceSupport(np.ones(1, dtype=bool), 0.0))


def test_oriented_normals_point_out_of_a_sphere_and_a_torus():
    for mesh in (icosphere(3), torus_grid(24, 12)):
        points, normals = sample_surface(mesh, 3000, np.random.default_rng(2))
        agree = np.einsum("ij,ij->i", oriented_normals(points), normals) > 0
        assert agree.mean() > 0.97


def test_trimming_keeps_the_validity_report_honest(sphere_points):
    _, points, normals = sphere_points
    kept, _, _ = shape_surface(icosphere(2), points[normals[:, 0] > 0], None, "open")
    report = check_topology(kept)
    assert not report.is_closed and report.is_valid(open_surface=True)
    assert not report.is_valid() and "boundary" in " ".join(report.defects())
    assert "boundary" not in " ".join(report.defects(open_surface=True))


def test_an_open_surface_loses_its_crossing_faces_and_keeps_its_guarantee():
    from spacemesh.geometry.intersections import self_intersecting_faces
    from spacemesh.geometry.surface import drop_crossing_faces

    sphere = icosphere(2)
    cap, _ = open_surface(sphere, support_of(sphere, sphere.face_normals()[:, 2] > 0.2))
    turned = cap.vertices @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]).T
    both = PolygonMesh(np.concatenate([cap.vertices, turned + np.array([0.0, 0.0, 0.3])]),
                       np.concatenate([cap.face_indices, cap.face_indices + cap.n_vertices]),
                       np.concatenate([cap.face_offsets[:-1],
                                       cap.face_offsets + cap.face_indices.size]))
    assert self_intersecting_faces(both).any()
    mended, dropped = drop_crossing_faces(both)
    assert dropped > 0 and not self_intersecting_faces(mended).any()
    assert_valid_mesh(mended, open_surface=True)
    same, none = drop_crossing_faces(cap)
    assert same is cap and none == 0
