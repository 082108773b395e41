"""What a repair returns: the repaired mesh (:class:`RepairResult`) and what was done
(:class:`RepairStats`), shared by :mod:`spacemesh.repair.api` and the re-generation of
grown regions (:mod:`spacemesh.repair.regrow`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import BoolArray, IntArray


def new_face_degrees(mesh: PolygonMesh, new: BoolArray) -> dict[int, int]:
    """How many of ``mesh``'s ``new`` faces ((F,) bool) have each number of corners (the
    stats' ``new_face_degrees``)."""
    sizes, counts = np.unique(mesh.face_sizes[new], return_counts=True)
    return {int(size): int(count) for size, count in zip(sizes, counts, strict=True)}


def add_timings(total: dict[str, float], more: dict[str, float]) -> None:
    """Add the seconds of ``more`` into ``total``, stage by stage (a repair run again)."""
    for key, value in more.items():
        total[key] = total.get(key, 0.0) + value


@dataclass
class RepairStats:
    """What a repair did (all JSON-serialisable through :meth:`to_dict`).

    Attributes
    ----------
    requested_faces, region_faces, grown_faces : int
        Faces the region selected, faces removed, and the difference (growth: pinched
        corners, and the kept faces a region still crossing took in,
        :mod:`spacemesh.repair.regrow`).
    removed_vertices, boundary_vertices, loops : int
    new_vertices, new_faces : int
    new_face_degrees : dict of int to int
    patch_faces, patch_rings, known_vertices, tokens : int
        The patch the model saw: faces, rings of context, held vertices, tokens.
    candidates : int
        Generated vertices offered to the connectivity network.
    fallback : {"none", "removed-new-vertices", "polygon"}
        ``removed-new-vertices`` when faces visiting a vertex twice or detached groups
        cost new vertices; ``polygon`` when at least one loop was closed by one polygon.
    fill : dict
        :attr:`spacemesh.repair.splice.Fill.stats`, and ``uncrossed_faces`` where every
        sampling's new faces crossed a face: how many of them
        :func:`spacemesh.repair.crossings.uncross_polygons` replaced; ``regrown_faces``
        and ``regrowths`` where a region still crossing was grown and repaired again
        (:func:`spacemesh.repair.regrow.regrow_crossings`), ``refilled_faces``,
        ``regrown_faces`` and ``refills`` where an automatic repair's crossing fills were
        made again (:func:`spacemesh.repair.regrow.refill_crossings`).
    inpaint : dict
        ``alive`` (free tokens alive by the mask), and of those dropped:
        ``outside_hole``, ``duplicates`` and ``over_limit`` (beyond the expected count).
    flipped_orientation : bool
        The input's faces wind clockwise (negative volume), so the network's cyclic
        orders were read reversed.
    welded_vertices : int
        Input vertices merged into another at the same position (``weld=True``; 0
        without).
    region_share : float
        Share of the mesh's faces the region covers after growth (the largest region's
        for an automatic region).
    auto_region : str
        ``holes``, ``defects`` or ``all`` for an automatic region, else "".
    passes : int
        Model passes run (1 for a marked region).
    reversed_faces : int
        Faces an automatic region's orientation reversed (:func:`spacemesh.repair.auto.
        orient_faces`).
    flipped_mesh : bool
        The whole mesh was inside out and was reversed.
    samplings : int
        Samplings of the region run: more than 1 where a fill that added a handle (its
        Euler characteristic below the region's) or whose new faces cross a face was
        sampled again, up to :data:`TOPOLOGY_ATTEMPTS` (summed over the passes of an
        automatic region, and over the repairs run again by
        :mod:`spacemesh.repair.regrow`); the fewest handles win, then the fewest crossing
        faces (of the fitted patch: not with ``fit_patch=False``).
    handles_added : int
        Handles the fill kept adds to the mesh (half the drop of its Euler characteristic
        below the region's): 0 unless every sampling added one, and then the sampling
        with the fewest is kept (the first of those with as few). For an automatic region,
        over the passes whose fill was kept (a region of holes whose fill is not one disc
        a loop takes the fan instead).
    findings : list of dict
        Automatic regions: every hole and defect found (first
        :data:`spacemesh.repair.findings.MAX_REPORTED`): ``kind``, ``size``, ``vertex``,
        ``region``, ``action``, and for holes ``filled_by`` (``model``, ``fallback`` or
        ``model-and-fallback``).
    findings_total : int
        Holes and defects found (all of them).
    regions : list of dict
        Automatic regions: each region's faces, growth (``grown_faces``, ``share``),
        ``strategy``, ``passes`` and ``filled_by`` (first ``MAX_REPORTED``).
    seed, steps : int
    method : str
    timings : dict of str to float
        Seconds: ``cut``, ``patch``, ``encoder``, ``sampler``, ``connectivity``,
        ``splice``, ``total``.
    """

    requested_faces: int = 0
    region_faces: int = 0
    grown_faces: int = 0
    removed_vertices: int = 0
    boundary_vertices: int = 0
    loops: int = 0
    new_vertices: int = 0
    new_faces: int = 0
    new_face_degrees: dict[int, int] = field(default_factory=dict)
    patch_faces: int = 0
    patch_rings: int = 0
    known_vertices: int = 0
    tokens: int = 0
    candidates: int = 0
    fallback: str = "none"
    fill: dict[str, int] = field(default_factory=dict)
    inpaint: dict[str, int] = field(default_factory=dict)
    flipped_orientation: bool = False
    welded_vertices: int = 0
    region_share: float = 0.0
    auto_region: str = ""
    passes: int = 1
    reversed_faces: int = 0
    flipped_mesh: bool = False
    samplings: int = 1
    handles_added: int = 0
    findings: list[dict[str, Any]] = field(default_factory=list)
    findings_total: int = 0
    regions: list[dict[str, Any]] = field(default_factory=list)
    seed: int = 0
    steps: int = 0
    method: str = ""
    timings: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (JSON keys are strings)."""
        data = asdict(self)
        data["new_face_degrees"] = {str(k): v for k, v in self.new_face_degrees.items()}
        return data


@dataclass(frozen=True)
class RepairResult:
    """A repaired mesh.

    Attributes
    ----------
    mesh : PolygonMesh
        Kept vertices in input order, then new vertices; kept faces in input order
        (each identical to its input face up to the vertex renumbering), then new faces.
        With ``weld=True`` the welded mesh is the input here: its vertices (the first
        copy of each position, in order of first occurrence) are renumbered.
    vertex_map : (V,) int64
        Output index of each input vertex, -1 for removed ones (with ``weld=True``, every
        copy of a position maps to the same output vertex).
    face_source : (F_out,) int64
        Input face of each output face, -1 for new faces.
    region : (F,) bool
        Input faces that were re-generated (the region after growth).
    stats : RepairStats
    """

    mesh: PolygonMesh
    vertex_map: IntArray
    face_source: IntArray
    region: BoolArray
    stats: RepairStats
