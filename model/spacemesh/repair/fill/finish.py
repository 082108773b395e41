"""Finishing a region of holes once the model's passes have filled it: its patch
refined and faired into the surface around it, or replaced by the fill the fairing, the
guards and the probe holes prefer (:func:`finish_holes`), as the
:class:`~spacemesh.repair.fill.policy.FillPolicy` says.

numpy and scipy only (MeshFix's fill: the optional ``pymeshfix``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from spacemesh.cancel import checkpoint
from spacemesh.geometry.intersections import crossing_faces
from spacemesh.primitives import faces_subset, triangulate_faces
from spacemesh.repair.fill.fan import faired_fan, fan_fill
from spacemesh.repair.fill.flat import flat_surface
from spacemesh.repair.fill.kinds import FilledBy, FillKind
from spacemesh.repair.fill.loops import patch_edge_length, patch_loops, patch_parts
from spacemesh.repair.fill.passes import Passes
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.repair.fill.probe import preferred_fill
from spacemesh.repair.fill.replace import fan_instead, flat_instead, meshfix_instead
from spacemesh.typed import BoolArray, IntArray


def finish_holes(state: Passes, index: int, by: FilledBy, policy: FillPolicy, *,
                 fair: bool = True, passes: Sequence[Any] = ()) -> FilledBy:
    """Finish the region of holes ``index`` once the model's passes have filled it: a
    fill that is not one disc a loop takes the fan (:func:`fan_if_not_discs`; its
    ``passes`` then report no handle), any other is refined and faired, or replaced, by
    the ``policy`` (:func:`fair_region`; not without ``fair``).

    Returns the region's ``filled_by``: ``by`` (what the passes did) unless a fallback
    or MeshFix's fill replaced the patch (:func:`replaced_by`).
    """
    if fan_if_not_discs(state, index, policy, passes):
        return FilledBy.FALLBACK
    if fair:
        by = replaced_by(fair_region(state, index, policy), by)
        return uncrossed_fill(state, index, policy) or by
    return by


def uncrossed_fill(state: Passes, index: int, policy: FillPolicy) -> FilledBy | None:
    """Where the faces the region ``index`` ended with cross a face (the fairing's
    membrane through the surface near a thin or concave part), the first of the faired
    fan, the least-area flat fill and MeshFix's fill whose faces cross nothing replaces
    them; its ``filled_by``, or None (none needed, none found, or not with the policy's
    ``uncrossed_fills``: the fill stays)."""
    if (not policy.uncrossed_fills
            or not len(crossing_faces(state.mesh, state.made_by == index))):
        return None
    tries: list[tuple[FilledBy, Callable[[], bool]]] = [
        (FilledBy.FALLBACK, lambda: fan_instead(state, index, policy)),
        (FilledBy.FALLBACK, lambda: flat_instead(state, index, state.made_by == index,
                                                 policy) is not None),
        (FilledBy.MESHFIX, lambda: meshfix_instead(state, index, policy)),
    ]
    for filled_by, attempt in tries:
        checkpoint()
        before = replace(state)  # every fill reassigns the state's fields, never mutates
        if attempt() and not len(crossing_faces(state.mesh, state.made_by == index)):
            return filled_by
        state.__dict__.update(before.__dict__)
    return None


def replaced_by(replaced: FillKind | None, by: FilledBy) -> FilledBy:
    """``filled_by`` once :func:`fair_region` has replaced the patch by ``replaced``
    (MeshFix's fill; the fan or the flat fill -- the fallback; or None: ``by`` stands)."""
    if replaced == FillKind.MESHFIX:
        return FilledBy.MESHFIX
    return FilledBy.FALLBACK if replaced in (FillKind.FAN, FillKind.FLAT) else by


def fair_region(state: Passes, index: int, policy: FillPolicy) -> FillKind | None:
    """Refine and fair the faces the region ``index`` made into the surface around them
    (the ``policy``'s fairing, :func:`spacemesh.repair.fill.fairing.fair_patch`).

    Where the fairing kept is one of the policy's
    :attr:`~spacemesh.repair.fill.policy.FillPolicy.meshfix_fairings`, they are replaced
    by MeshFix's fill of the same loops (:func:`~spacemesh.repair.fill.replace.
    meshfix_instead`). Where the faired patch could be moved only part of the way (it
    would cross itself or the surface: the model's tessellation folds once curved), it
    is replaced by a fan over its loops, refined and faired the same way, when that one
    moves all the way (:func:`~spacemesh.repair.fill.replace.fan_instead`). A patch
    faired all the way is laid onto that faired fan's surface (:func:`onto_fan`, with
    ``lay_onto_fan``), or replaced by it where it would fold there. With
    ``probe_fills``, each hole of the region (each part of its patch,
    :func:`~spacemesh.repair.fill.loops.patch_parts`) whose probe holes prefer MeshFix's
    fill (:func:`probe_choice`) then takes it, and one whose probes prefer the
    least-area flat fill is laid onto it (:func:`onto_flat`); a patch left held back
    around which no probe fits takes MeshFix's fill too (``unchecked_fills``).

    Returns :attr:`FillKind.MESHFIX` when MeshFix's fill was taken for any hole of the
    region, :attr:`FillKind.FLAT` when the flat fill replaced the patch of one
    (:func:`~spacemesh.repair.fill.replace.flat_instead`: the probes prefer it, and the
    patch could not be laid onto it), :attr:`FillKind.FAN` when the faired fan replaced
    the patch, None otherwise.
    """
    mesh = state.mesh
    patch = state.made_by == index
    report: dict[str, Any] = {}
    faired, source, _ = policy.fair(mesh, patch, state.origin == index,
                                    patch_edge_length(mesh, patch), report=report)
    state.apply(np.arange(mesh.n_vertices), source, faired, index)
    if report.get("fairing") in policy.meshfix_fairings:
        return FillKind.MESHFIX if meshfix_instead(state, index, policy) else None
    held_back = False  # the patch left is moved only part of the way to its fairing
    replaced: FillKind | None
    if report.get("weight", 1.0) < 1.0:
        replaced = FillKind.FAN if fan_instead(state, index, policy) else None
        held_back = replaced is None
    else:
        replaced = FillKind.FAN if (policy.lay_onto_fan and onto_fan(state, index, policy)
                                    == FillKind.FAN) else None
    if not policy.probe_fills:
        return replaced
    checkpoint()
    chosen = np.zeros(state.mesh.n_faces, dtype=bool)
    flat_parts: list[BoolArray] = []  # parts the flat fill replaces
    for part in patch_parts(state.mesh, state.made_by == index):
        checkpoint()  # abandoned work stops here (spacemesh.cancel)
        choice = probe_choice(state, part, policy, held_back=held_back)
        if choice == FillKind.MESHFIX:
            chosen |= part
        elif choice == FillKind.FLAT and not onto_flat(state, part, policy):
            flat_parts.append(part)
    for i, part in enumerate(flat_parts):
        checkpoint()
        renumbered = flat_instead(state, index, part, policy)
        if renumbered is None:
            continue
        replaced = FillKind.FLAT  # each replacement renumbers the faces: the masks follow

        def follow(mask: BoolArray, source: IntArray = renumbered) -> BoolArray:
            return np.where(source >= 0, mask[np.maximum(source, 0)], False)

        chosen = follow(chosen)
        flat_parts[i + 1:] = [follow(later) for later in flat_parts[i + 1:]]
    if chosen.any() and meshfix_instead(state, index, policy, chosen):
        return FillKind.MESHFIX
    return replaced


def onto_fan(state: Passes, index: int, policy: FillPolicy) -> FillKind | None:
    """Lay the faired patch of the region ``index`` onto the surface of the faired fan
    over the same loops (:func:`~spacemesh.repair.fill.fan.faired_fan`): the model's
    tessellation, with the geometry of the fairing the probe holes judge
    (:mod:`spacemesh.repair.fill.probe`).

    The fairing of the model's own patch follows its tessellation: an uneven one bends
    the thin plate into ridges and spikes (on the dev split the faired fan lay closer to
    the intact surface on most holes, up to 50 times). Each of the patch's own vertices
    moves to its closest point on the fan's faces (the ``policy``'s
    :func:`~spacemesh.repair.fill.lay.lay_onto`, fitted with ``fit_laid``); where a face
    stays folded there, or the patch would add a self-intersection, the fan replaces the
    patch instead (:func:`~spacemesh.repair.fill.replace.fan_instead`).

    Returns :attr:`FillKind.PROJECTED`, :attr:`FillKind.FAN` (the fan replaced the
    patch) or None (no faired fan: the patch stays).
    """
    mesh = state.mesh
    patch = state.made_by == index
    fan = faired_fan(mesh, patch, policy)
    if fan is None:
        return None
    faired, _, made = fan
    fan_triangles, _ = triangulate_faces(faces_subset(faired, made))  # (T, 3)
    positions = policy.lay_onto(mesh, patch, faired.vertices, fan_triangles,
                                fit=policy.fit_laid, relax_rounds=policy.relax_rounds)
    if positions is None:
        return FillKind.FAN if fan_instead(state, index, policy, fan) else None
    state.mesh = mesh.with_vertices(positions)
    return FillKind.PROJECTED


def onto_flat(state: Passes, part: BoolArray, policy: FillPolicy) -> bool:
    """Lay the patch faces ``part`` ((F,) bool: one hole's) onto the least-area flat
    triangulation of their loops (:func:`spacemesh.repair.fill.flat.flat_surface`), where
    the probe holes prefer that fill (:func:`probe_choice`); True when it did (the
    ``policy``'s :func:`~spacemesh.repair.fill.lay.lay_onto`)."""
    mesh = state.mesh
    loops = patch_loops(mesh, part)
    triangles = flat_surface(mesh.vertices, loops, policy.max_flat_loop) if loops else None
    if triangles is None:
        return False
    positions = policy.lay_onto(mesh, part, mesh.vertices, triangles,
                                relax_rounds=policy.relax_rounds)
    if positions is None:
        return False
    state.mesh = mesh.with_vertices(positions)
    return True


def probe_choice(state: Passes, part: BoolArray, policy: FillPolicy,
                 held_back: bool = False) -> FillKind:
    """The fill the probe holes punched in the input faces around the hole that the
    patch faces ``part`` ((F,) bool) fill prefer: :attr:`FillKind.FAIR`,
    :attr:`FillKind.MESHFIX` or :attr:`FillKind.FLAT`
    (:func:`spacemesh.repair.fill.probe.preferred_fill`).

    Where the patch is ``held_back`` (its fairing could be applied only part of the
    way, as the full move would cross the surface, and no faired fan replaced it) and
    no probe hole fits around it, nothing read from the input confirms the fairing:
    with the ``policy``'s ``unchecked_fills``, MeshFix's fill is taken, or the flat one
    where MeshFix has none."""
    loops = patch_loops(state.mesh, part)
    if not loops:
        return FillKind.FAIR
    known = (state.made_by < 0)[~part]  # input faces of the mesh with the hole open
    opened = faces_subset(state.mesh, ~part)
    report: dict[str, Any] = {}
    choice = preferred_fill(opened, loops, known, report=report, policy=policy)
    if not (policy.unchecked_fills and held_back and report["probe_holes"] == 0):
        return choice
    return FillKind.MESHFIX if policy.meshfix_fill(opened, loops) is not None else FillKind.FLAT


def fan_if_not_discs(state: Passes, index: int, policy: FillPolicy,
                     passes: Sequence[Any] = ()) -> bool:
    """Replace the faces the region ``index`` made by a fan over each of their loops
    (faired, :func:`~spacemesh.repair.fill.fan.faired_fan`, or as it is where it cannot
    be) when they are not one disc a loop: a fill whose Euler characteristic (the
    ``policy``'s ``euler``) differs from its number of loops joins them by a tube or a
    handle (a model pass can splice one in), which changes the genus of the mesh. True
    when it did; then the region's ``passes`` (their
    :class:`spacemesh.repair.api.RepairStats`) report no handle added, as none of
    their fill is left."""
    mesh = state.mesh
    patch = state.made_by == index
    loops = patch_loops(mesh, patch)
    if not loops or policy.euler(mesh, patch) == len(loops):
        return False
    fan = faired_fan(mesh, patch, policy)
    if fan is None:  # the plain fan: one disc a loop however it lies
        filled, _ = fan_fill(faces_subset(mesh, ~patch), loops)
        source = np.concatenate([np.flatnonzero(~patch),
                                 np.full(filled.n_faces - int((~patch).sum()), -1)])
        fan = (filled, source, source < 0)
    replaced = fan_instead(state, index, policy, fan)
    for stats in passes if replaced else ():
        stats.handles_added = 0
    return replaced
