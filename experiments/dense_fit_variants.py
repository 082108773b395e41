"""Run an evaluation with the dense decode's fit, the final fit or the seeds' choice changed.

The shipped pipeline fits a dense decode to the points before collapsing it to the
count asked for (``spacemesh.geometry.finishing.finish_geometry``). This script runs
``spacemesh eval`` or ``experiments/eval_real_meshes.py`` in-process with that first fit
replaced (the fit after the collapses is untouched), and optionally the seeds' ranking
(``spacemesh.runtime.choice``) changed, so that each variant is measured by the same
evaluation as the shipped code (docs/GEOMETRY.md, "Compact meshes"; 2026-12-07).

Variants of the dense fit (``--dense-fit``):

- ``shipped``: as the code is (no flips since 2026-12-07, ``dense_flips``);
- ``with-flips``: the rounds of fit with diagonal flips between them (before);
- ``none``: no fit before the collapses (the raw decode collapsed);
- ``one-round``: one round of fit (no flips), the guard on;
- ``one-round-no-guard``: the same without the self-intersection guard;
- ``no-flips``: the rounds of fit without the diagonal flips between them.

``--final-fit`` changes the fit after the collapses (the calls with ``target_vertices``)
the same way: ``shipped``, ``one-round``, ``three-rounds`` or ``no-flips``.

``--near-contacts-rank``: the seeds' ranking counts near contacts as crossings (not only
the check that sends the retry seeds). ``--genus-vote``: among three or more seeds, one
whose genus is the most common among them ranks before one whose genus is not (after
pieces and crossings, before the fit score).

Usage::

    python experiments/dense_fit_variants.py --dense-fit no-flips -- eval --data DATA
        --split all --limit 50 --out OUT --modes default --baselines none --threads 1
    python experiments/dense_fit_variants.py --dense-fit no-flips -- \\
        experiments/eval_real_meshes.py --split dev --modes default --baselines none
"""

from __future__ import annotations

import argparse
import collections
import runpy
import sys
from dataclasses import replace
from typing import Any

import numpy as np

VARIANTS = ("shipped", "with-flips", "none", "one-round", "one-round-no-guard", "no-flips")
FINAL_VARIANTS = ("shipped", "one-round", "three-rounds", "no-flips")
CHANGES: dict[str, dict[str, Any]] = {
    "one-round": {"rounds": 1}, "one-round-no-guard": {"rounds": 1, "guard": False},
    "three-rounds": {"rounds": 3}, "no-flips": {"flips": False},
    "with-flips": {"flips": True}}


def patch_fits(variant: str, final: str = "shipped") -> None:
    """Replace the fit before the collapses (the calls without ``target_vertices``) by
    ``variant`` and the fit after them by ``final``."""
    import spacemesh.geometry.finishing as finishing
    from spacemesh.geometry.stage import GeometryResult

    shipped = finishing.refine_geometry

    def dense_fit(mesh: Any, points: Any, normals: Any = None, options: Any = None,
                  **kwargs: Any) -> Any:
        if "target_vertices" in kwargs:
            changes = CHANGES.get(final, {})
            return shipped(mesh, points, normals, replace(options, **changes), **kwargs)
        if variant == "shipped":
            return shipped(mesh, points, normals, options, **kwargs)
        if variant == "none":
            return GeometryResult(mesh, {})
        return shipped(mesh, points, normals, replace(options, **CHANGES[variant]), **kwargs)

    finishing.refine_geometry = dense_fit


def patch_ranking(near_contacts: bool, genus_vote: bool) -> None:
    """Change how :func:`spacemesh.runtime.choice.best_fit` ranks the seeds."""
    import spacemesh.runtime.choice as choice
    import spacemesh.runtime.pipeline as pipeline
    from spacemesh.geometry.intersections import near_contact_faces

    if near_contacts:
        plain = choice.crosses
        choice.crosses = lambda r: plain(r) or bool(near_contact_faces(r.mesh).any())
    if not genus_vote:
        return

    def best_fit(tried: list[Any], options: Any, expected_pieces: int, *,
                 check: bool = True) -> Any:
        def score(result: Any) -> float:
            value = result.fit.score if result.fit is not None else float("nan")
            return value if np.isfinite(value) else float("inf")

        scores = [(r.seed, score(r)) for r in tried]
        genera = [r.fit.genus if r.fit is not None else -1 for r in tried]
        counts = collections.Counter(g for g in genera if g >= 0)
        top = max(counts.values(), default=0)
        modal = ({g for g, c in counts.items() if c == top} if len(tried) >= 3
                 else set(genera))

        def rank(i: int) -> tuple[bool, bool, bool, float, int]:
            return (check and not choice.pieces_agree(tried[i], expected_pieces),
                    check and choice.crosses(tried[i]), check and genera[i] not in modal,
                    scores[i][1], scores[i][0])

        winner = tried[min(range(len(tried)), key=rank)]
        winner.options = replace(options, seed=winner.seed)
        winner.sample_scores = scores
        return winner

    pipeline.best_fit = best_fit


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dense-fit", choices=VARIANTS, default="shipped")
    parser.add_argument("--final-fit", choices=FINAL_VARIANTS, default="shipped")
    parser.add_argument("--near-contacts-rank", action="store_true")
    parser.add_argument("--genus-vote", action="store_true")
    parser.add_argument("command", nargs=argparse.REMAINDER,
                        help="after --: 'eval ...' or a script path and its arguments")
    args = parser.parse_args()
    command = [c for c in args.command if c != "--"]
    if not command:
        parser.error("give the evaluation to run after --")
    patch_fits(args.dense_fit, args.final_fit)
    patch_ranking(args.near_contacts_rank, args.genus_vote)
    if command[0].endswith(".py"):
        sys.argv = command
        runpy.run_path(command[0], run_name="__main__")
    else:
        from spacemesh.cli import main as cli

        sys.argv = ["spacemesh", *command]
        cli()


if __name__ == "__main__":
    main()
