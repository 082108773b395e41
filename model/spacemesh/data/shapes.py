"""Random CAD-like solids built by constructive solid geometry with manifold3d.

A shape is a *base* solid (box, chamfered or filleted box, cylinder, cone, sphere,
torus, tetrahedron, extruded or revolved random polygon), unioned with a few more
primitives that overlap it, and then cut by subtractions: through-holes, pockets
and slots. This gives genus above 0 (through-holes, tori, rings), concave sharp
features (unions of boxes, pockets, slots), and flat and curved regions side by
side. Most parts are axis-aligned, as real CAD parts are.

The geometry is exact CSG; tessellation styles (:mod:`spacemesh.data.styles`)
re-mesh the result. Nothing here validates: manifold3d silently splits pinched
edges, so everything stored goes through :mod:`spacemesh.data.validate`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from spacemesh.mesh import PolygonMesh

#: Primitives a shape may be built from (the paper's four plus the CAD ones).
PRIMITIVES = (
    "cube",
    "tetrahedron",
    "sphere",
    "cylinder",
    "cone",
    "torus",
    "chamfered_box",
    "filleted_box",
    "extrusion",
    "revolution",
)
#: Subtractions that cut features into the unioned solid.
CUTS = ("through_hole", "pocket", "slot")

# Relative frequencies of primitives as the base and as additions: boxes dominate
# real CAD parts, so they dominate here too.
_BASE_WEIGHTS = {
    "cube": 4,
    "chamfered_box": 2,
    "filleted_box": 2,
    "cylinder": 2,
    "extrusion": 3,
    "revolution": 2,
    "sphere": 1,
    "cone": 1,
    "torus": 1,
    "tetrahedron": 1,
}
_ADD_WEIGHTS = {
    "cube": 5,
    "cylinder": 3,
    "sphere": 1,
    "tetrahedron": 1,
    "cone": 1,
    "chamfered_box": 1,
    "filleted_box": 1,
    "extrusion": 2,
    "torus": 0.5,
    "revolution": 0.5,
}


@dataclass
class ShapeRecipe:
    """What a random shape is made of (stored with the shape, for statistics)."""

    base: str
    additions: list[str] = field(default_factory=list)
    cuts: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """Plain dict for JSON."""
        return {"base": self.base, "additions": list(self.additions), "cuts": list(self.cuts)}


def _m3():
    import manifold3d

    return manifold3d


def _choice(rng: np.random.Generator, weights: Mapping[str, float]) -> str:
    names = list(weights)
    p = np.array([weights[n] for n in names], dtype=np.float64)
    return names[int(rng.choice(len(names), p=p / p.sum()))]


def _star_polygon(rng: np.random.Generator, radius: float) -> np.ndarray:
    """(K, 2) a random simple star-shaped polygon, counter-clockwise."""
    k = int(rng.integers(3, 9))
    angles = np.sort(rng.uniform(0.0, 2 * np.pi, k))
    # Keep angular gaps from collapsing so the polygon has no needle spikes.
    gaps = np.diff(np.concatenate([angles, [angles[0] + 2 * np.pi]]))
    if gaps.min() < 0.25 or gaps.max() > 0.8 * np.pi:  # needles, or the origin outside
        angles = np.linspace(0, 2 * np.pi, k, endpoint=False) + rng.uniform(0, 2 * np.pi)
    concave = rng.random() < 0.5
    radii = radius * (rng.uniform(0.45, 1.0, k) if concave else np.full(k, 1.0))
    return np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)


def primitive(name: str, rng: np.random.Generator, size: float, segments: int):
    """One primitive solid of roughly ``size`` extent, centred near the origin.

    Parameters
    ----------
    name : str
        One of :data:`PRIMITIVES`.
    rng : numpy.random.Generator
    size : float
        Characteristic extent.
    segments : int
        Circular segments for curved primitives.

    Returns
    -------
    manifold3d.Manifold
    """
    m3 = _m3()
    Manifold, CrossSection = m3.Manifold, m3.CrossSection
    dims = size * rng.uniform(0.4, 1.0, 3)
    if name == "cube":
        return Manifold.cube(tuple(dims), center=True)
    if name == "tetrahedron":
        return Manifold.tetrahedron().scale(tuple(dims / 1.6))
    if name == "sphere":
        return Manifold.sphere(float(dims[0] / 2), circular_segments=segments)
    if name == "cylinder":
        return Manifold.cylinder(
            float(dims[2]), float(dims[0] / 2), circular_segments=segments, center=True
        )
    if name == "cone":
        top = float(dims[0] / 2 * rng.choice([0.0, rng.uniform(0.2, 0.7)]))
        return Manifold.cylinder(
            float(dims[2]), float(dims[0] / 2), top, circular_segments=segments, center=True
        )
    if name == "torus":
        major = size / 2 * rng.uniform(0.6, 1.0)
        minor = major * rng.uniform(0.2, 0.45)
        circle = CrossSection.circle(minor, circular_segments=max(8, segments // 2))
        return circle.translate((major, 0.0)).revolve(circular_segments=segments)
    if name == "chamfered_box":
        c = float(dims.min() * rng.uniform(0.1, 0.3))
        x, y, z = (float(d) for d in dims)
        if rng.random() < 0.5:  # all twelve edges
            parts = [
                Manifold.cube((x, y - 2 * c, z - 2 * c), center=True),
                Manifold.cube((x - 2 * c, y, z - 2 * c), center=True),
                Manifold.cube((x - 2 * c, y - 2 * c, z), center=True),
            ]
        else:  # the four vertical edges only
            parts = [
                Manifold.cube((x, y - 2 * c, z), center=True),
                Manifold.cube((x - 2 * c, y, z), center=True),
            ]
        return Manifold.batch_hull(parts)
    if name == "filleted_box":
        r = float(dims[:2].min() * rng.uniform(0.1, 0.3))
        x, y, z = (float(d) for d in dims)
        rect = CrossSection.square((x - 2 * r, y - 2 * r), center=True)
        rounded = rect.offset(r, m3.JoinType.Round, circular_segments=segments)
        return rounded.extrude(z).translate((0.0, 0.0, -z / 2))
    if name == "extrusion":
        poly = _star_polygon(rng, size / 2)
        height = float(size * rng.uniform(0.2, 0.9))
        return CrossSection([poly]).extrude(height).translate((0.0, 0.0, -height / 2))
    if name == "revolution":
        k = int(rng.integers(2, 5))
        heights = np.sort(rng.uniform(-size / 2, size / 2, k))
        inner = size / 2 * (rng.uniform(0.1, 0.35) if rng.random() < 0.4 else 0.0)
        radii = size / 2 * rng.uniform(0.3, 1.0, k)
        radii = np.maximum(radii, inner + 0.1 * size)
        profile = [(inner, heights[0])]
        profile += [(float(r), float(h)) for r, h in zip(radii, heights, strict=True)]
        profile += [(inner, heights[-1])]
        cross = CrossSection([np.array(profile)])
        return cross.revolve(circular_segments=segments)
    raise ValueError(f"unknown primitive {name!r}")


def _orient(solid, rng: np.random.Generator, axis_aligned: bool):
    """Rotate by a random multiple of 90 degrees per axis, or arbitrarily."""
    if axis_aligned:
        angles = 90.0 * rng.integers(0, 4, 3)
    else:
        angles = rng.uniform(0.0, 360.0, 3)
    return solid.rotate(tuple(float(a) for a in angles))


def _bounds(solid) -> tuple[np.ndarray, np.ndarray]:
    box = np.asarray(solid.bounding_box(), dtype=np.float64)  # (6,) min xyz, max xyz
    return box[:3], box[3:]


def _through_hole(rng, lo, hi, segments):
    m3 = _m3()
    axis = int(rng.integers(0, 3))
    others = [a for a in range(3) if a != axis]
    extent = hi - lo
    span = float(extent[others].min())
    radius = span * rng.uniform(0.06, 0.18)
    length = float(extent[axis] * 3 + 1.0)
    centre = lo + extent * rng.uniform(0.25, 0.75, 3)
    if rng.random() < 0.75:
        tool = m3.Manifold.cylinder(length, radius, circular_segments=segments, center=True)
    else:
        tool = m3.Manifold.cube((2 * radius, 2 * radius, length), center=True)
    return _align_z_to(tool, axis).translate(tuple(centre.tolist()))


def _pocket(rng, lo, hi, segments):
    m3 = _m3()
    axis = int(rng.integers(0, 3))
    side = int(rng.integers(0, 2))
    others = [a for a in range(3) if a != axis]
    extent = hi - lo
    depth = float(extent[axis] * rng.uniform(0.15, 0.5))
    w = extent[others] * rng.uniform(0.15, 0.45, 2)
    if rng.random() < 0.6:
        tool = m3.Manifold.cube((float(w[0]), float(w[1]), 2 * depth), center=True)
    else:
        tool = m3.Manifold.cylinder(
            2 * depth, float(w.min() / 2), circular_segments=segments, center=True
        )
    tool = _align_z_to(tool, axis)
    centre = lo + extent * rng.uniform(0.3, 0.7, 3)
    centre[axis] = hi[axis] if side else lo[axis]
    return tool.translate(tuple(centre.tolist()))


def _slot(rng, lo, hi, segments):
    m3 = _m3()
    axis = int(rng.integers(0, 3))
    others = [a for a in range(3) if a != axis]
    extent = hi - lo
    width = float(extent[others].min() * rng.uniform(0.08, 0.2))
    length = float(extent[others[0]] * rng.uniform(0.3, 0.6))
    through = rng.random() < 0.5
    depth = (
        float(extent[axis] * 3 + 1.0) if through else float(extent[axis] * rng.uniform(0.3, 0.6))
    )
    if rng.random() < 0.5:  # rounded ends: the hull of two cylinders
        end = m3.Manifold.cylinder(depth, width / 2, circular_segments=segments, center=True)
        tool = m3.Manifold.batch_hull(
            [end.translate((-length / 2, 0.0, 0.0)), end.translate((length / 2, 0.0, 0.0))]
        )
    else:
        tool = m3.Manifold.cube((length, width, depth), center=True)
    tool = _align_z_to(tool, axis, first=others[0])
    centre = lo + extent * rng.uniform(0.3, 0.7, 3)
    if not through:
        centre[axis] = hi[axis] if rng.random() < 0.5 else lo[axis]
    return tool.translate(tuple(centre.tolist()))


def _align_z_to(tool, axis: int, first: int | None = None):
    """Rotate a tool built along z (and x) so that z becomes ``axis`` (x becomes ``first``)."""
    if axis == 2:
        return tool if first in (None, 0) else tool.rotate((0.0, 0.0, 90.0))
    if axis == 0:  # z -> x
        tool = tool.rotate((0.0, 90.0, 0.0))  # x -> -z, z -> x
        return tool if first in (None, 1) else tool.rotate((90.0, 0.0, 0.0))
    tool = tool.rotate((-90.0, 0.0, 0.0))  # z -> y
    return tool if first in (None, 0) else tool.rotate((0.0, 90.0, 0.0))


def random_solid(rng: np.random.Generator, segments: int = 32):
    """A random CSG solid: base, unions and cuts.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness (the same state gives the same solid).
    segments : int
        Circular segments of curved primitives (sets the tessellation density).

    Returns
    -------
    solid : manifold3d.Manifold
        The largest connected piece of the result (may be empty).
    recipe : ShapeRecipe
    """
    base_name = _choice(rng, _BASE_WEIGHTS)
    recipe = ShapeRecipe(base=base_name)
    axis_aligned = rng.random() < 0.85
    solid = _orient(primitive(base_name, rng, 2.0, segments), rng, True)
    if solid.is_empty():  # a degenerate random profile; the caller draws again
        return solid, recipe
    for _ in range(int(rng.choice([0, 1, 2, 3, 4], p=[0.2, 0.3, 0.25, 0.15, 0.1]))):
        name = _choice(rng, _ADD_WEIGHTS)
        lo, hi = _bounds(solid)
        part = _orient(
            primitive(name, rng, float(rng.uniform(0.5, 1.4)), segments), rng, axis_aligned
        )
        # Centre the part on the base's bounding box surface so that it protrudes.
        centre = rng.uniform(lo, hi)
        axis = int(rng.integers(0, 3))
        centre[axis] = hi[axis] if rng.random() < 0.5 else lo[axis]
        centre[axis] += -0.3 * np.sign(centre[axis] - (lo[axis] + hi[axis]) / 2) * 0.5
        solid = solid + part.translate(tuple(centre.tolist()))
        recipe.additions.append(name)
    n_cuts = int(rng.choice([0, 1, 2, 3], p=[0.25, 0.35, 0.25, 0.15]))
    for _ in range(n_cuts):
        cut = str(rng.choice(CUTS, p=[0.45, 0.35, 0.2]))
        lo, hi = _bounds(solid)
        make = {"through_hole": _through_hole, "pocket": _pocket, "slot": _slot}[cut]
        candidate = solid - make(rng, lo, hi, segments)
        if candidate.is_empty():
            continue
        solid = candidate
        recipe.cuts.append(cut)
    pieces = solid.decompose()
    if len(pieces) > 1:
        solid = max(pieces, key=lambda piece: piece.volume())
    return solid, recipe


def solid_to_mesh(solid) -> PolygonMesh:
    """The triangle mesh of a manifold3d solid.

    Parameters
    ----------
    solid : manifold3d.Manifold

    Returns
    -------
    PolygonMesh
        Triangles, counter-clockwise seen from outside.
    """
    mesh = solid.to_mesh64()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]  # (V, 3)
    triangles = np.asarray(mesh.tri_verts, dtype=np.int64).reshape(-1, 3)  # (T, 3)
    return PolygonMesh.from_faces(vertices, triangles)
