"""Which model gets which refinement: the manifest's ``decode`` section.

The export writes the section from the model's data card (:func:`decode_section`); the
runtime reads it back into :class:`~spacemesh.decode.DecodeOptions` fields
(:func:`decode_changes`). The section's format is fixed: a repository written before a
key existed keeps that field's default, so every shipped model version loads as it did.
"""

from __future__ import annotations

from typing import Any

#: The manifest ``decode`` keys that are :class:`~spacemesh.decode.DecodeOptions` fields.
DECODE_KEYS = ("max_sides", "reinsert", "flip", "flat_delaunay_degrees", "fit_gain")

#: The relative gain a point-fit flip of the decode needs: chosen on the val split of
#: the ``qem`` set of seed 5, never on the held-out set (100 shapes, version 5's
#: graphs, decoded edge F1 0.962 / 0.964 / 0.964 / 0.962 for 0.1 / 0.3 / 0.5 / 0.7;
#: ``experiments/decode_fit_sweep.py``).
FIT_GAIN = 0.5

#: Generator styles whose meshes are all triangles (a model trained on them should output
#: triangles); :mod:`spacemesh.data.styles` makes them.
TRIANGLE_STYLES = ("qem", "isotropic")

#: Triangles whose normals are within this angle count as coplanar for the generator's
#: Delaunay flips (:func:`spacemesh.data.styles.delaunay_flip_flat`), and so for the decode.
FLAT_FLIP_DEGREES = 1.0


def decode_changes(section: dict[str, Any]) -> dict[str, Any]:
    """:class:`~spacemesh.decode.DecodeOptions` fields from a manifest's ``decode``
    section (:data:`DECODE_KEYS`; a repository written before a key existed keeps that
    field's default)."""
    return {key: section[key] for key in DECODE_KEYS if key in section}


def decode_section(data_card: dict[str, Any]) -> dict[str, Any]:
    """The manifest's ``decode`` section for a model trained on ``data_card``'s data.

    A model trained on triangle meshes (:data:`TRIANGLE_STYLES`)
    has its long faces cut into triangles (``max_sides`` 3, see
    :mod:`spacemesh.decode.splitting`), then its removed vertices put back and its
    diagonals flipped to the ones it rates closer (``reinsert``, ``flip``, see
    :mod:`spacemesh.decode.refinement`); one trained on ``qem`` meshes of generator
    1.1.0 or later, whose flat quads have the Delaunay diagonal, gets that rule too
    (``flat_delaunay_degrees``, the generator's :data:`FLAT_FLIP_DEGREES`). Triangle models
    also flip toward the conditioning points
    (``fit_gain`` :data:`FIT_GAIN`, see :func:`spacemesh.decode.refinement.flip_diagonals`).
    Any other keeps its polygons as matched.

    Parameters
    ----------
    data_card : dict
        The run's data card (``style`` and ``generator_version`` are read).

    Returns
    -------
    dict
        ``max_sides`` (int or None), ``reinsert``, ``flip`` (bool),
        ``flat_delaunay_degrees``, ``fit_gain`` (float or None) and ``why``.
    """
    style = data_card.get("style")
    if style not in TRIANGLE_STYLES:
        return {"max_sides": None, "reinsert": False, "flip": False,
                "flat_delaunay_degrees": None, "fit_gain": None,
                "why": f"trained on style {style}: polygons are kept"}
    version = tuple(int(v) for v in str(data_card.get("generator_version", "0")).split("."))
    flat = FLAT_FLIP_DEGREES if style == "qem" and version >= (1, 1, 0) else None
    why = (f"trained on triangle meshes (style {style}): faces longer than triangles are "
           "cut along their strongest missing diagonals, removed vertices go back into "
           "the triangles rated closest, and diagonals flip to the ones whose triangles "
           f"pass closer to the points (by more than {FIT_GAIN:g} of the squared "
           "distance), or else to the ones rated closer")
    if flat is not None:
        why += (f"; quads folded by less than {flat:g} degree are Delaunay, as in the "
                f"training meshes (generator {data_card['generator_version']})")
    return {"max_sides": 3, "reinsert": True, "flip": True, "flat_delaunay_degrees": flat,
            "fit_gain": FIT_GAIN, "why": why}
