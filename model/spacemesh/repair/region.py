"""The region a user marks for repair, in the mesh's own coordinates.

Five forms, as JSON (the REST body, the gRPC message and the CLI all map to these):

``{"faces": [f, ...]}``
    Face indices.
``{"vertices": [v, ...]}``
    Vertex indices: every face that uses one of them.
``{"sphere": {"center": [x, y, z], "radius": r}}``
    Every face with at least one vertex inside the closed ball.
``{"box": {"min": [x, y, z], "max": [x, y, z]}}``
    Every face with at least one vertex inside the closed axis-aligned box.
``{"auto": "holes" | "defects" | "all"}``
    Found automatically (:mod:`spacemesh.repair.auto`): every boundary loop (a hole)
    with the ring of faces around it, every non-manifold edge or vertex and pinched or
    degenerate face with its neighbourhood, or both; each is repaired as a region of
    its own.

:class:`RegionError` carries a stable ``kind`` that the service turns into the
problem+json ``type`` of its 422 answers (see :data:`ERROR_KINDS`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from spacemesh.errors import KindedError
from spacemesh.mesh import PolygonMesh
from spacemesh.repair.findings import auto_faces
from spacemesh.typed import BoolArray, FloatArray, IntArray

RegionKind = Literal["faces", "vertices", "sphere", "box", "auto"]
REGION_KINDS: tuple[str, ...] = ("faces", "vertices", "sphere", "box", "auto")
#: The values of an ``{"auto": ...}`` region: what it selects.
AUTO_MODES: tuple[str, ...] = ("holes", "defects", "all")
#: Largest share of the mesh's faces a region may grow to (``max_growth``) by default.
DEFAULT_MAX_GROWTH = 0.25

#: The region selects no face.
EMPTY_REGION = "empty-region"
#: The region (possibly after growing it, see :mod:`spacemesh.repair.cut`) is every face.
WHOLE_MESH_REGION = "whole-mesh-region"
#: The region is malformed: unknown form, bad numbers, indices out of range.
INVALID_REGION = "invalid-region"
#: The mesh has defects (open boundary, non-manifold or misoriented edges, pinched
#: vertices, degenerate faces) that the region does not cover.
DEFECTS_OUTSIDE_REGION = "defects-outside-region"
#: The region's boundary alone needs more vertex tokens than the model has.
REGION_TOO_LARGE = "region-too-large"

#: Growth (:func:`spacemesh.repair.cut.grow_region`) would take the region beyond the
#: allowed share of the mesh's faces (``max_growth``).
REGION_GROWTH_EXCEEDED = "region-growth-exceeded"
#: An automatic region found a surface that cannot be oriented (a Moebius strip).
NON_ORIENTABLE = "non-orientable"

#: Every kind a :class:`RegionError` may carry.
ERROR_KINDS: tuple[str, ...] = (
    EMPTY_REGION, WHOLE_MESH_REGION, INVALID_REGION, DEFECTS_OUTSIDE_REGION, REGION_TOO_LARGE,
    REGION_GROWTH_EXCEEDED, NON_ORIENTABLE,
)


class RegionError(KindedError):
    """A repair request that cannot be served as asked (an HTTP 422).

    Parameters
    ----------
    kind : str
        One of :data:`ERROR_KINDS`, stable across versions.
    message : str
        One human-readable sentence.
    details : dict, optional
        Machine-readable context, e.g. ``{"defects": [...]}`` for
        ``defects-outside-region``.
    """

    KINDS = ERROR_KINDS


def _invalid(message: str) -> RegionError:
    return RegionError(INVALID_REGION, message)


def _indices(values: Any, what: str) -> IntArray:
    """A flat int64 array of indices (rejecting floats with a fraction, bools, NaN)."""
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise _invalid(f"{what} must be a list of integers") from error
    if array.dtype == object and array.ndim == 1 and all(
            isinstance(v, int) and not isinstance(v, bool) for v in array.tolist()):
        # integers beyond int64 (numpy keeps them as Python objects)
        _refuse_huge(array.tolist(), what)
    if array.dtype == object or array.dtype.kind == "b":
        raise _invalid(f"{what} must be a list of integers")
    array = array.reshape(-1)
    if array.size == 0:
        return np.zeros(0, dtype=np.int64)
    if array.dtype.kind == "f":
        if not np.all(np.isfinite(array)) or np.any(array != np.round(array)):
            raise _invalid(f"{what} must be a list of integers")
    elif array.dtype.kind not in "iu":
        raise _invalid(f"{what} must be a list of integers")
    _refuse_huge(array.tolist(), what)
    return array.astype(np.int64)


def _refuse_huge(values: list[Any], what: str) -> None:
    """Raise ``invalid-region`` naming the first index, as sent, that int64 cannot hold
    (so that it is never wrapped around into another index)."""
    limit = int(np.iinfo(np.int64).max)
    for value in values:
        if not -limit <= value <= limit:
            raise _invalid(f"{what}: index {value!r} is out of range")


def check_range(indices: IntArray, count: int, noun: str, plural: str) -> None:
    """Raise ``invalid-region`` unless every index is in ``0 .. count - 1``.

    Parameters
    ----------
    indices : (K,) int64
    count : int
        Faces or vertices of the mesh.
    noun, plural : str
        ``"face", "faces"`` or ``"vertex", "vertices"`` (for the message).
    """
    bad = indices[(indices < 0) | (indices >= count)]
    if bad.size:
        raise _invalid(f"{noun} index {int(bad[0])} is out of range: the mesh has "
                       f"{count} {plural}")


def _point(values: Any, what: str) -> FloatArray:
    """A finite (3,) float64 point."""
    try:
        array = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as error:
        raise _invalid(f"{what} must be three numbers") from error
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise _invalid(f"{what} must be three finite numbers")
    return array


@dataclass(frozen=True, eq=False)
class Region:
    """A region of a mesh; build it with the class methods or :func:`parse_region`.

    Attributes
    ----------
    kind : {"faces", "vertices", "sphere", "box", "auto"}
    indices : (K,) int64
        Face or vertex indices (``faces`` and ``vertices`` forms).
    center : (3,) float64
        Sphere centre.
    radius : float
        Sphere radius.
    lower, upper : (3,) float64
        Box corners.
    mode : {"holes", "defects", "all"} or None
        What an ``auto`` region selects.
    """

    kind: RegionKind
    indices: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    center: FloatArray | None = None
    radius: float = 0.0
    lower: FloatArray | None = None
    upper: FloatArray | None = None
    mode: str | None = None

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_faces(cls, faces: Sequence[int] | IntArray) -> Region:
        """The faces with these indices."""
        return cls("faces", indices=_indices(faces, "region faces"))

    @classmethod
    def from_vertices(cls, vertices: Sequence[int] | IntArray) -> Region:
        """Every face that uses one of these vertices."""
        return cls("vertices", indices=_indices(vertices, "region vertices"))

    @classmethod
    def sphere(cls, center: Sequence[float] | FloatArray, radius: float) -> Region:
        """Every face with a vertex inside the closed ball."""
        try:
            r = float(radius)
        except (TypeError, ValueError) as error:
            raise _invalid("the sphere's radius must be a number") from error
        if not np.isfinite(r) or r <= 0:
            raise _invalid("the sphere's radius must be a positive finite number")
        return cls("sphere", center=_point(center, "the sphere's center"), radius=r)

    @classmethod
    def box(cls, lower: Sequence[float] | FloatArray, upper: Sequence[float] | FloatArray
            ) -> Region:
        """Every face with a vertex inside the closed axis-aligned box."""
        lo, hi = _point(lower, "the box's min"), _point(upper, "the box's max")
        if np.any(lo > hi):
            raise _invalid("the box's min must not exceed its max on any axis")
        return cls("box", lower=lo, upper=hi)

    @classmethod
    def auto(cls, mode: str) -> Region:
        """Found automatically: ``holes``, ``defects`` or ``all`` (both)."""
        if not isinstance(mode, str) or mode not in AUTO_MODES:
            raise _invalid(f"an auto region is one of {', '.join(AUTO_MODES)}, not {mode!r}")
        return cls("auto", mode=mode)

    @property
    def is_auto(self) -> bool:
        """An ``{"auto": ...}`` region (repaired region by region, see
        :mod:`spacemesh.repair.auto`)."""
        return self.kind == "auto"

    # ------------------------------------------------------------------ selection
    def vertex_mask(self, vertices: FloatArray) -> BoolArray:
        """(V,) vertices inside a sphere or box region."""
        if self.kind == "sphere":
            assert self.center is not None  # Region.sphere sets it
            with np.errstate(over="ignore"):  # a radius past 1e154 squares to inf
                d2 = np.sum((vertices - self.center) ** 2, axis=1)
                return d2 <= np.float64(self.radius) ** 2
        if self.kind == "box":
            assert self.lower is not None and self.upper is not None  # Region.box sets them
            return np.all((vertices >= self.lower) & (vertices <= self.upper), axis=1)
        raise ValueError(f"a {self.kind} region has no vertex test")

    def face_mask(self, mesh: PolygonMesh) -> BoolArray:
        """(F,) the faces of ``mesh`` in this region.

        Raises
        ------
        RegionError
            ``invalid-region`` when an index is out of range.
        """
        if self.kind == "faces":
            check_range(self.indices, mesh.n_faces, "face", "faces")
            mask = np.zeros(mesh.n_faces, dtype=bool)
            mask[self.indices] = True
            return mask
        if self.kind == "auto":
            return auto_faces(mesh, str(self.mode))
        if self.kind == "vertices":
            check_range(self.indices, mesh.n_vertices, "vertex", "vertices")
            inside = np.zeros(mesh.n_vertices, dtype=bool)
            inside[self.indices] = True
        else:
            inside = self.vertex_mask(mesh.vertices)
        mask = np.zeros(mesh.n_faces, dtype=bool)
        mask[mesh.face_of_corner[inside[mesh.face_indices]]] = True
        return mask

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (inverse of :func:`parse_region`)."""
        if self.kind in ("faces", "vertices"):
            return {self.kind: self.indices.tolist()}
        if self.kind == "auto":
            return {"auto": self.mode}
        if self.kind == "sphere":
            assert self.center is not None  # Region.sphere sets it
            return {"sphere": {"center": self.center.tolist(), "radius": self.radius}}
        assert self.lower is not None and self.upper is not None  # a box: Region.box sets them
        return {"box": {"min": self.lower.tolist(), "max": self.upper.tolist()}}


def parse_region(data: object) -> Region:
    """Read the JSON form of a region (see the module docstring).

    Parameters
    ----------
    data : dict or Region
        Exactly one of the keys ``faces``, ``vertices``, ``sphere``, ``box``, ``auto``;
        anything else (any JSON value, a face mask that is not boolean) is refused.

    Returns
    -------
    Region

    Raises
    ------
    RegionError
        ``invalid-region`` for anything malformed.
    """
    if isinstance(data, Region):
        return data
    if not isinstance(data, Mapping):
        raise _invalid("the region must be an object with one of the keys "
                       + ", ".join(REGION_KINDS))
    keys = [k for k in REGION_KINDS if data.get(k) is not None]
    unknown = sorted(set(data) - set(REGION_KINDS))
    if unknown:
        raise _invalid(f"unknown region key {unknown[0]!r}; use one of "
                       + ", ".join(REGION_KINDS))
    if len(keys) != 1:
        raise _invalid("the region must have exactly one of the keys " + ", ".join(REGION_KINDS))
    kind = keys[0]
    value = data[kind]
    if kind == "faces":
        return Region.from_faces(value)
    if kind == "vertices":
        return Region.from_vertices(value)
    if kind == "auto":
        return Region.auto(value)
    if not isinstance(value, Mapping):
        raise _invalid(f"the region's {kind} must be an object")
    if kind == "sphere":
        if "center" not in value or "radius" not in value:
            raise _invalid("a sphere region needs center and radius")
        return Region.sphere(value["center"], value["radius"])
    if "min" not in value or "max" not in value:
        raise _invalid("a box region needs min and max")
    return Region.box(value["min"], value["max"])


def region_faces(mesh: PolygonMesh, region: Region | Mapping[str, Any]) -> BoolArray:
    """(F,) faces of ``mesh`` selected by ``region``, checked to be neither none nor all.

    Raises
    ------
    RegionError
        ``invalid-region``, ``empty-region`` or ``whole-mesh-region``.
    """
    mask = parse_region(region).face_mask(mesh)
    if not mask.any():
        raise RegionError(EMPTY_REGION, "the region selects no face of the mesh")
    if mask.all():
        raise RegionError(WHOLE_MESH_REGION, "the region covers the whole mesh; repair needs "
                                             "faces outside the region to keep")
    return mask
