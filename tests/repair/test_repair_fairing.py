"""Hole patches refined and faired into the surface around them
(:mod:`spacemesh.repair.fill.fairing` and the modules it uses)."""

from __future__ import annotations

import numpy as np
import pytest
from auto_meshes import cylinder, punched

from spacemesh.examples import icosphere, torus_grid
from spacemesh.mesh import PolygonMesh
from spacemesh.primitives.closest import closest_points_on_triangles
from spacemesh.repair.cut import defect_vertices
from spacemesh.repair.fill.fairing import fair_patch
from spacemesh.repair.fill.fan import fan_fill
from spacemesh.repair.fill.flat import flat_positions, min_area_triangles
from spacemesh.repair.fill.laplace import fair_positions
from spacemesh.repair.fill.loops import boundary_edge_length, patch_edge_length, patch_loops
from spacemesh.repair.fill.planar import planar_positions
from spacemesh.repair.fill.refine import refine_patch
from spacemesh.repair.pinched import hole_loops
from spacemesh.topology import check_topology


def fan_filled(mesh):
    """``mesh``'s holes closed by centroid fans: (filled mesh, new faces, new vertices,
    loops)."""
    loops = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    filled, fans = fan_fill(mesh, loops)
    patch = np.zeros(filled.n_faces, dtype=bool)
    patch[np.concatenate(fans)] = True
    free = np.arange(filled.n_vertices) >= mesh.n_vertices
    return filled, patch, free, loops


def test_a_sphere_hole_is_faired_onto_the_sphere():
    mesh = punched(icosphere(4), [[0.0, 0.0, 1.0]], radius=0.55)
    filled, patch, free, loops = fan_filled(mesh)
    flat_error = abs(np.linalg.norm(filled.vertices[free], axis=1) - 1).max()
    out, source, added = fair_patch(filled, patch, free, boundary_edge_length(filled, loops))
    assert added > 10  # refined to the ring's density
    assert check_topology(out).is_closed_oriented_manifold
    kept = source >= 0  # the input's faces are the same polygons
    before, after = filled.faces, out.faces
    assert [tuple(after[f]) for f in np.flatnonzero(kept)] == [
        tuple(before[s]) for s in source[kept]]
    assert np.array_equal(out.vertices[:mesh.n_vertices], mesh.vertices)
    error = abs(np.linalg.norm(out.vertices[mesh.n_vertices:], axis=1) - 1)
    # the flat fan's centre is off the sphere by the cap's height; the faired patch is
    # within a fifth of that everywhere
    assert flat_error > 0.15 and error.max() < 0.2 * flat_error, (flat_error, error.max())


def test_a_cylinder_hole_is_faired_onto_the_cylinder():
    mesh = punched(cylinder(24, 12), [[1.0, 0.0, 0.0]], radius=0.6)
    filled, patch, free, loops = fan_filled(mesh)
    out, _, added = fair_patch(filled, patch, free, boundary_edge_length(filled, loops))
    new = out.vertices[mesh.n_vertices:]
    radial = abs(np.linalg.norm(new[:, :2], axis=1) - 1)
    assert added > 5 and check_topology(out).is_closed_oriented_manifold
    assert radial.max() < 0.03, radial.max()  # the cap's height is 0.17


def test_a_torus_hole_takes_the_tri_harmonic_surface_closer_than_a_thin_plate():
    # on the outer equator the curvature changes across the hole: the thin plate
    # (C1) flattens it, the tri-harmonic surface (C2) continues it
    torus = torus_grid(48, 24, triangulate_every=1)  # major radius 2, minor 1
    mesh = punched(torus, [[3.0, 0.0, 0.0]], radius=0.9)
    filled, patch, free, loops = fan_filled(mesh)
    target = boundary_edge_length(filled, loops)
    report = {}
    out, _, _ = fair_patch(filled, patch, free, target, report=report)

    def off_torus(points):
        return abs(np.hypot(np.linalg.norm(points[:, :2], axis=1) - 2.0, points[:, 2]) - 1.0)

    refined, _ = refine_patch(filled, patch, target)
    moving = np.arange(refined.n_vertices) >= mesh.n_vertices
    plate = off_torus(fair_positions(refined, moving, 2)[moving]).max()
    error = off_torus(out.vertices[mesh.n_vertices:]).max()
    assert report["fairing"] == "tri-harmonic" and report["weight"] == 1.0, report
    assert check_topology(out).is_closed_oriented_manifold
    assert error < 0.7 * plate, (error, plate)  # 0.050 against 0.090


def test_refinement_splits_only_interior_edges_and_fairing_keeps_fixed_vertices():
    mesh = punched(icosphere(3), [[0.0, 0.0, 1.0]], radius=0.5)
    filled, patch, _, loops = fan_filled(mesh)
    target = boundary_edge_length(filled, loops)
    refined, _ = refine_patch(filled, patch, target)
    assert refined.n_vertices > filled.n_vertices
    ring_edges = {frozenset(e) for loop in loops for e in zip(loop, np.roll(loop, -1), strict=True)}
    assert ring_edges <= {frozenset(e) for e in refined.edges.tolist()}  # never split
    fixed = np.zeros(refined.n_vertices, dtype=bool)
    fixed[:mesh.n_vertices] = True
    faired = fair_positions(refined, ~fixed)
    assert np.array_equal(faired[fixed], refined.vertices[fixed])
    assert not np.allclose(faired[~fixed], refined.vertices[~fixed])
    # nothing free: nothing moves; a long target: nothing is split
    assert np.array_equal(fair_positions(refined, np.zeros_like(fixed)), refined.vertices)
    same, identity = refine_patch(filled, patch, 100.0)
    assert same is filled and np.array_equal(identity, np.arange(filled.n_faces))


def test_one_polygon_over_a_hole_is_fanned_refined_and_faired():
    mesh = punched(icosphere(4), [[0.0, 0.0, 1.0]], radius=0.55)
    [loop] = hole_loops(mesh, np.flatnonzero(defect_vertices(mesh)))
    closed = PolygonMesh.from_faces(mesh.vertices, [*mesh.faces, loop])
    patch = np.arange(closed.n_faces) == closed.n_faces - 1
    target = patch_edge_length(closed, patch)
    assert np.isclose(target, boundary_edge_length(closed, [loop]))
    out, source, added = fair_patch(closed, patch, np.zeros(closed.n_vertices, dtype=bool),
                                    target)
    assert added > 10 and (source == -1).sum() > len(loop)
    assert check_topology(out).is_closed_oriented_manifold
    error = abs(np.linalg.norm(out.vertices[mesh.n_vertices:], axis=1) - 1)
    assert error.max() < 0.04, error.max()


def grid_box(n: int = 8) -> PolygonMesh:
    """The cube [-1, 1]^3 with ``n`` x ``n`` quads on each side, each split in two
    triangles (sharp edges and corners)."""
    t = np.linspace(-1.0, 1.0, n + 1)
    u, v = np.meshgrid(t, t, indexing="ij")
    points, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            grid = np.zeros((n + 1, n + 1, 3))
            grid[..., axis] = sign
            grid[..., (axis + 1) % 3], grid[..., (axis + 2) % 3] = u, v
            base = sum(len(p) for p in points)
            ids = base + np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
            for i in range(n):
                for j in range(n):
                    a, b, c, d = ids[i, j], ids[i + 1, j], ids[i + 1, j + 1], ids[i, j + 1]
                    quad = [a, b, c, d] if sign > 0 else [a, d, c, b]
                    faces += [quad[:3], [quad[0], quad[2], quad[3]]]
            points.append(grid.reshape(-1, 3))
    merged, index = np.unique(np.round(np.concatenate(points), 9), axis=0, return_inverse=True)
    return PolygonMesh.from_faces(merged, index.ravel()[np.asarray(faces)].tolist())


def cube_distance(x: np.ndarray) -> np.ndarray:
    """Distance of each point to the surface of the cube [-1, 1]^3."""
    outside = np.linalg.norm(np.maximum(abs(x) - 1.0, 0.0), axis=1)
    return np.where(outside > 0, outside, 1.0 - abs(x).max(axis=1))


def test_a_hole_across_a_box_edge_is_filled_piecewise_planar():
    box = grid_box(8)
    assert check_topology(box).is_closed_oriented_manifold
    mesh = punched(box, [[1.0, 1.0, 0.0]], radius=0.6)
    filled, patch, free, loops = fan_filled(mesh)
    out, _, added = fair_patch(filled, patch, free, boundary_edge_length(filled, loops))
    assert added > 5 and check_topology(out).is_closed_oriented_manifold
    error = cube_distance(out.vertices[mesh.n_vertices:])
    # the plain thin plate over the same refined patch bulges off the crease
    refined, _ = refine_patch(filled, patch, boundary_edge_length(filled, loops))
    plate = fair_positions(refined, np.arange(refined.n_vertices) >= mesh.n_vertices)
    bulge = cube_distance(plate[mesh.n_vertices:])
    assert bulge.max() > 0.1, bulge.max()
    assert error.max() < 0.05, (error.max(), bulge.max())


def test_a_smooth_ring_is_not_read_as_sharp():
    mesh = punched(icosphere(4), [[0.0, 0.0, 1.0]], radius=0.55)
    filled, patch, free, _ = fan_filled(mesh)
    assert planar_positions(filled, free, patch, filled.vertices) is None


def test_least_area_triangulation_of_a_polygon():
    """A convex planar polygon: n - 2 triangles of the polygon's area, all facing one way;
    a folded (saddle) loop: no more area than the fan from its first corner."""
    angles = np.linspace(0, 2 * np.pi, 7)[:-1]
    hexagon = np.stack([np.cos(angles), np.sin(angles), np.zeros(6)], axis=1)
    triangles = min_area_triangles(hexagon)
    corners = hexagon[triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert triangles.shape == (4, 3) and (normals[:, 2] > 0).all()
    assert 0.5 * normals[:, 2].sum() == pytest.approx(3 * np.sqrt(3) / 2)
    saddle = np.stack([np.cos(angles), np.sin(angles), 0.5 * np.cos(2 * angles)], axis=1)
    corners = saddle[min_area_triangles(saddle)]
    fan = saddle[[[0, k, k + 1] for k in range(1, 5)]]

    def area(c):
        return 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1).sum()

    assert area(corners) <= area(fan) + 1e-12


def test_flat_fill_lies_on_the_least_area_triangulation_of_its_loop():
    box = grid_box(8)
    mesh = punched(box, [[1.0, 1.0, 0.0]], radius=0.6)  # a hole across a box edge
    filled, patch, _, loops = fan_filled(mesh)
    refined, source = refine_patch(filled, patch, boundary_edge_length(filled, loops))
    moving = np.arange(refined.n_vertices) >= mesh.n_vertices
    new_patch = source < 0
    [loop] = patch_loops(refined, new_patch)
    assert sorted(loop.tolist()) == sorted(loops[0].tolist())
    base = fair_positions(refined, moving, 1, "uniform")
    flat = flat_positions(refined, moving, new_patch, base)
    assert flat is not None and np.array_equal(flat[~moving], refined.vertices[~moving])
    corners = refined.vertices[loop][min_area_triangles(refined.vertices[loop])]
    for x in flat[moving]:  # on one of the triangles
        on = closest_points_on_triangles(np.repeat(x[None], len(corners), axis=0), corners)
        assert np.linalg.norm(on - x, axis=1).min() < 1e-9
    assert flat_positions(refined, moving, new_patch, base, max_loop=len(loop)) is not None
    assert flat_positions(refined, moving, new_patch, base, max_loop=len(loop) - 1) is None
