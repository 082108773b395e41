"""The fill policy: which fills a region of holes may end with, the margins the probe
holes decide by, and the fill functions themselves (:class:`FillPolicy`).

One frozen value, passed explicitly from :func:`spacemesh.repair.repair_mesh` down to
every fill; the default is the policy the docs report (docs/REPAIR.md, step 5). The
switches exist for comparisons (``experiments/eval_repair_holes.py``), the functions so
that an experiment or a test can put a stand-in in place of one fill.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from spacemesh.mesh import PolygonMesh
from spacemesh.repair.fill.fairing import fair_patch
from spacemesh.repair.fill.flat import MAX_FLAT_LOOP
from spacemesh.repair.fill.kinds import Fairing, FillKind
from spacemesh.repair.fill.lay import RELAX_ROUNDS, lay_onto
from spacemesh.repair.fill.loops import patch_euler
from spacemesh.repair.fill.meshfix import meshfix_fill
from spacemesh.typed import BoolArray, FloatArray, IntArray

#: ``fair_patch(mesh, patch, free, target, *, report=..., max_flat_loop=...)``:
#: :func:`spacemesh.repair.fill.fairing.fair_patch`.
FairFn = Callable[..., tuple[PolygonMesh, IntArray, int]]
#: ``meshfix_fill(mesh, loops)``: :func:`spacemesh.repair.fill.meshfix.meshfix_fill`.
MeshfixFn = Callable[[PolygonMesh, list[IntArray]], tuple[FloatArray, IntArray] | None]
#: ``lay_onto(mesh, patch, points, triangles, *, fit=..., relax_rounds=...)``:
#: :func:`spacemesh.repair.fill.lay.lay_onto`.
LayFn = Callable[..., FloatArray | None]
#: ``euler(mesh, faces)``: :func:`spacemesh.repair.fill.loops.patch_euler`.
EulerFn = Callable[[PolygonMesh, BoolArray], int]


@dataclass(frozen=True)
class FillPolicy:
    """How the holes of an automatic region are filled once the model's passes are done.

    Attributes
    ----------
    lay_onto_fan : bool
        A patch faired all the way is laid onto the surface of the faired fan over its
        loops (:func:`spacemesh.repair.fill.finish.onto_fan`).
    fit_laid : bool
        The patch laid onto the faired fan is then fitted to its surface in the
        least-squares sense (:func:`spacemesh.repair.fill.lay.lay_onto`).
    probe_fills : bool
        MeshFix's fill, or the flat one, replaces the fairing's patch of a hole where
        probe holes punched around it say it is closer
        (:func:`spacemesh.repair.fill.probe.preferred_fill`).
    unchecked_fills : bool
        A hole whose patch could be faired only part of the way, and around which no
        probe hole fits, takes MeshFix's fill (or the flat one)
        (:func:`spacemesh.repair.fill.finish.probe_choice`).
    uncrossed_fills : bool
        A region whose finished fill crosses a face takes the first of the faired fan,
        the flat fill and MeshFix's fill that crosses nothing
        (:func:`spacemesh.repair.fill.finish.uncrossed_fill`; issue 35, "Repairs add no
        crossings").
    meshfix_fairings : tuple of Fairing
        The fairings (the ``fairing`` :func:`fair_patch` reports) whose patch MeshFix's
        fill of the same loops replaces: the least-area flat fill, used where both thin
        plates overshoot the ring (sharp surroundings), imitates MeshFix's, and
        MeshFix's own (triangulated, refined, faired) was closer on the dev split.
    meshfix_margin : float
        MeshFix's fill is taken when its summed probe error is below this share of the
        fairing's. 2.0 (MeshFix's fill unless the probes favour the fairing two to one)
        was tried in session 17: fewer losses to MeshFix on dev, one more on the test
        split (docs/REPAIR.md, step 5).
    probe_margin : float
        Another alternative is taken when its summed probe error is below this share of
        the fairing's.
    alternatives : tuple of FillKind
        The fills the probes weigh against the fairing's, in order (the first of equal
        ones wins): MeshFix's (triangulated, refined, faired) and the least-area flat
        triangulation of the loop, which continues a piecewise-flat surface (a plate's
        rim, a low-poly facet) where both others bulge.
    max_flat_loop : int
        Longest loop the least-area triangulation is built for (its dynamic programme
        takes ``O(n^3)`` work; :mod:`spacemesh.repair.fill.flat`).
    relax_rounds : int
        Rounds of tangential relaxation tried on a laid patch with a folded or
        collapsed face (:func:`spacemesh.repair.fill.lay.lay_onto`).
    fair_patch, meshfix_fill, lay_onto, euler : callable
        The fairing, MeshFix's fill, the laying onto a surface, and the Euler
        characteristic of a fill's faces (a model pass samples again while its fill's
        is below the region's; a region of holes whose fill is not one disc a loop
        takes the fan): every fill and probe calls these, so a stand-in given here
        replaces that step everywhere.
    """

    lay_onto_fan: bool = True
    fit_laid: bool = True
    probe_fills: bool = True
    unchecked_fills: bool = True
    uncrossed_fills: bool = True
    meshfix_fairings: tuple[Fairing, ...] = (Fairing.FLAT,)
    meshfix_margin: float = 0.8
    probe_margin: float = 0.8
    alternatives: tuple[FillKind, ...] = (FillKind.MESHFIX, FillKind.FLAT)
    max_flat_loop: int = MAX_FLAT_LOOP
    relax_rounds: int = RELAX_ROUNDS
    fair_patch: FairFn = fair_patch
    meshfix_fill: MeshfixFn = meshfix_fill
    lay_onto: LayFn = lay_onto
    euler: EulerFn = patch_euler

    def __post_init__(self) -> None:
        # names given as plain strings become members (a member and its string are
        # equal, but only members key the probes' tables)
        object.__setattr__(self, "meshfix_fairings",
                           tuple(Fairing(name) for name in self.meshfix_fairings))
        object.__setattr__(self, "alternatives",
                           tuple(FillKind(name) for name in self.alternatives))

    def fair(self, mesh: PolygonMesh, patch: BoolArray, free: BoolArray, target: float,
             report: dict[str, Any] | None = None) -> tuple[PolygonMesh, IntArray, int]:
        """:attr:`fair_patch` with this policy's :attr:`max_flat_loop`."""
        return self.fair_patch(mesh, patch, free, target, report=report,
                               max_flat_loop=self.max_flat_loop)


#: The policy the docs report: every default.
DEFAULT_POLICY = FillPolicy()
