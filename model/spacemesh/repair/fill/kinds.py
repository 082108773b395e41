"""The names of a hole's fills and of what filled it, as string enums.

Each member is its string (``FillKind.MESHFIX == "meshfix"``), so a report that holds one
serialises as that string (``json.dumps`` writes the value); where a name is formatted
into text, write its ``.value`` (an f-string of a member writes ``FillKind.MESHFIX`` in
Python 3.11). The reports themselves hold the plain values.
"""

from __future__ import annotations

from enum import Enum


class FillKind(str, Enum):
    """A fill a hole's patch can take after the model's passes
    (:mod:`spacemesh.repair.fill.finish`)."""

    #: The model's patch, refined and faired into the surface around it.
    FAIR = "fair"
    #: The model's patch laid onto the surface of the faired fan over its loops.
    PROJECTED = "projected"
    #: A fan over each loop, refined and faired (the patch replaced).
    FAN = "fan"
    #: MeshFix's fill of the loops (:mod:`spacemesh.repair.fill.meshfix`).
    MESHFIX = "meshfix"
    #: The least-area flat triangulation of the loops (:mod:`spacemesh.repair.fill.flat`).
    FLAT = "flat"


class FilledBy(str, Enum):
    """What filled a hole: the ``filled_by`` of its finding and region in a report."""

    #: The model's passes, every loop or wedge.
    MODEL = "model"
    #: A fallback: the fan, the flat fill, or the splice's one polygon over a loop.
    FALLBACK = "fallback"
    #: The model for some loops or wedges, a fallback for the others.
    MODEL_AND_FALLBACK = "model-and-fallback"
    #: MeshFix's fill.
    MESHFIX = "meshfix"


class Fairing(str, Enum):
    """The continuation :func:`spacemesh.repair.fill.fairing.fair_patch` kept (its
    report's ``fairing``)."""

    TRI_HARMONIC = "tri-harmonic"
    THIN_PLATE = "thin-plate"
    THIN_PLATE_UNIFORM = "thin-plate-uniform"
    MEMBRANE = "membrane"
    #: The membrane projected onto the least-area flat triangulation of the loops.
    FLAT = "flat"
    #: The piecewise-planar continuation of a sharp ring.
    PLANAR = "planar"
    #: None stayed within the ring's box: the positions as they were.
    NONE = "none"
