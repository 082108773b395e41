"""Splicing: fitted embeddings re-fill a hole exactly; any embeddings close it validly."""

from __future__ import annotations

import numpy as np
import pytest
from repair_testing import (
    KP,
    N_SPACE,
    K,
    assert_closed_manifold,
    fitted_embeddings,
    geometric_faces,
    subset,
)

from spacemesh.decode import DecodeOptions, Embeddings
from spacemesh.examples import cube_quads, icosphere, prism, torus_grid
from spacemesh.repair.cut import cut_region
from spacemesh.repair.region import Region
from spacemesh.repair.splice import fill_hole, splice

OPTIONS = DecodeOptions(n_space=N_SPACE)

CASES = {
    "icosphere-2-ring": (lambda: icosphere(2), lambda m: Region.sphere(m.vertices[0], 0.35)),
    "icosphere-star": (lambda: icosphere(1), lambda m: Region.from_vertices([3])),
    "torus-mixed": (lambda: torus_grid(8, 6, triangulate_every=3),
                    lambda m: Region.from_vertices([0, 1, 7])),
    "cube-corner": (cube_quads, lambda m: Region.from_vertices([0])),
    "prism-cap-vertex": (lambda: prism(6), lambda m: Region.from_vertices([0, 1])),
    "one-triangle": (lambda: icosphere(1), lambda m: Region.from_faces([3])),
}


def refill(mesh, cut, emb, positions):
    fill = fill_hole(emb, len(cut.boundary), cut.loop_next, cut.loop_prev, OPTIONS)
    return fill, splice(cut, positions, fill)


def assert_kept_unchanged(mesh, cut, spliced):
    n_kept = len(cut.kept_faces)
    out = spliced.mesh
    assert np.array_equal(spliced.face_source[:n_kept], cut.kept_faces)
    assert (spliced.face_source[n_kept:] == -1).all()
    for f_out, f_in in zip(out.faces[:n_kept], cut.kept_faces, strict=True):
        original = mesh.faces[f_in]
        assert np.array_equal(spliced.vertex_map[original], f_out)
        assert np.array_equal(out.vertices[f_out], mesh.vertices[original])


@pytest.mark.parametrize("name", sorted(CASES))
def test_fitted_embeddings_give_the_original_back(name):
    pytest.importorskip("torch")
    make, region = CASES[name]
    mesh = make()
    emb = fitted_embeddings(mesh)
    cut = cut_region(mesh, region(mesh))
    rows = np.concatenate([cut.boundary, cut.removed_vertices])
    fill, spliced = refill(mesh, cut, subset(emb, rows), mesh.vertices[cut.removed_vertices])
    assert fill.stats["n_unpinched"] == 0 and fill.stats["n_pruned"] == 0
    assert spliced.n_new_vertices == len(cut.removed_vertices)
    assert spliced.n_new_faces == int(cut.region.sum())
    assert geometric_faces(spliced.mesh) == geometric_faces(mesh)
    assert_kept_unchanged(mesh, cut, spliced)
    assert_closed_manifold(spliced.mesh)


def random_embeddings(rng, n, scale=1.0) -> Embeddings:
    return Embeddings(rng.normal(0, scale, (n, K)), float(rng.normal(0, 2)),
                      *(rng.normal(size=(n, KP)) for _ in range(3)))


REGIONS = {
    "icosphere": (lambda: icosphere(2), lambda m: Region.sphere(m.vertices[5], 0.6)),
    "torus-band": (lambda: torus_grid(12, 8),
                   lambda m: Region.box([-4, -0.2, -2], [4, 0.2, 2])),
    "cube-two-loops": (cube_quads, lambda m: Region.from_faces([0, 1, 2, 3])),
    "prism": (lambda: prism(7), lambda m: Region.from_faces([0])),
}


@pytest.mark.parametrize("name", sorted(REGIONS))
def test_any_embeddings_close_the_hole_validly(name):
    make, region = REGIONS[name]
    mesh = make()
    cut = cut_region(mesh, region(mesh))
    for seed in range(8):
        rng = np.random.default_rng(seed)
        m = int(rng.integers(0, 30))
        emb = random_embeddings(rng, len(cut.boundary) + m, scale=float(rng.uniform(0.2, 2)))
        if seed % 4 == 3:  # sprinkle non-finite entries
            emb.adjacency[rng.integers(0, emb.n_vertices, 3)] = np.nan
            emb.root[rng.integers(0, emb.n_vertices, 3), 0] = np.inf
        _, spliced = refill(mesh, cut, emb, rng.normal(size=(m, 3)))
        assert_closed_manifold(spliced.mesh)
        assert_kept_unchanged(mesh, cut, spliced)
        assert spliced.mesh.n_vertices == mesh.n_vertices - len(cut.removed_vertices) + \
            spliced.n_new_vertices


def test_no_new_vertices_closes_each_loop_with_one_polygon():
    mesh = cube_quads()
    cut = cut_region(mesh, Region.from_faces([0, 1, 2, 3]))
    emb = random_embeddings(np.random.default_rng(0), len(cut.boundary))
    fill, spliced = refill(mesh, cut, emb, np.zeros((0, 3)))
    assert fill.stats["polygon_loops"] == 2 and spliced.n_new_faces == 2
    new_faces = [tuple(f) for f in spliced.mesh.faces[len(cut.kept_faces):]]
    loops = {tuple(spliced.vertex_map[loop]) for loop in cut.loops}
    assert {min(tuple(np.roll(f, -k)) for k in range(len(f))) for f in new_faces} == {
        min(tuple(np.roll(loop, -k)) for k in range(len(loop))) for loop in loops}
    assert_closed_manifold(spliced.mesh)


def test_new_vertices_far_from_every_threshold_are_removed():
    mesh = icosphere(1)
    cut = cut_region(mesh, Region.from_vertices([0]))
    rng = np.random.default_rng(1)
    emb = random_embeddings(rng, len(cut.boundary) + 3)
    emb = Embeddings(emb.adjacency, -1e9, emb.root, emb.prev, emb.next)  # no edge at all
    fill, spliced = refill(mesh, cut, emb, rng.normal(size=(3, 3)))
    assert fill.stats["n_pruned"] == 3 and spliced.n_new_vertices == 0
    assert fill.stats["polygon_loops"] == 1
    assert_closed_manifold(spliced.mesh)


def test_new_crossings_counts_the_new_faces_that_cross():
    """The repair samples a region again while its fitted patch's new faces cross a face
    (spacemesh.repair.crossings.new_crossings): new faces crossing kept or new ones count, kept
    faces crossing each other do not."""
    from spacemesh.mesh import PolygonMesh
    from spacemesh.repair.crossings import new_crossings
    from spacemesh.repair.splice import Spliced

    a, b = icosphere(2), icosphere(2)

    def spliced(offset, new_first):
        vertices = np.concatenate([a.vertices, b.vertices + np.array(offset)])
        faces = [list(f) for f in a.faces] + [[i + a.n_vertices for i in f] for f in b.faces]
        mesh = PolygonMesh.from_faces(vertices, faces)
        source = np.arange(mesh.n_faces)
        source[a.n_faces:] = -1  # the second sphere's faces are new ...
        if new_first:  # ... or the first's
            source = np.where(source < 0, np.arange(mesh.n_faces), -1)
        return Spliced(mesh, np.arange(mesh.n_vertices), source, b.n_vertices, b.n_faces)

    assert new_crossings(spliced([3.0, 0, 0], False)) == 0
    crossing = new_crossings(spliced([0.8, 0.1, 0], False))
    assert 0 < crossing < b.n_faces
    assert 0 < new_crossings(spliced([0.8, 0.1, 0], True)) < a.n_faces
