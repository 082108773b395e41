"""Which of a request's seeds gives its mesh: the topology check and the best fit.

The decode's topology and crossings depend on the seed (docs/GEOMETRY.md, "The seeds'
topology check"): a mesh with as many pieces as the points is preferred to any without,
then one whose faces do not cross, then the best fit score, then the lower seed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from spacemesh.geometry.intersections import near_contact_faces
from spacemesh.runtime.options import GenerateOptions
from spacemesh.runtime.request import GenerateResult


def pieces_agree(result: GenerateResult, expected: int) -> bool:
    """Whether ``result``'s mesh has ``expected`` pieces (the points' own count)."""
    return result.fit is not None and result.fit.pieces == expected


def crosses(result: GenerateResult) -> bool:
    """Whether ``result``'s mesh has faces that intersect others (its fit report)."""
    return result.fit is None or result.fit.self_intersections != 0


def acceptable(result: GenerateResult, expected: int) -> bool:
    """As many pieces as the points and no crossing faces, nor faces that nearly touch
    (:func:`spacemesh.geometry.intersections.near_contact_faces`): no other seed is
    needed. A first seed with a near contact lets the retry seeds run, whose best fit
    is kept (docs/GEOMETRY.md, "The held-out CAD-like parts")."""
    return (pieces_agree(result, expected) and not crosses(result)
            and not near_contact_faces(result.mesh).any())


def fit_score_of(result: GenerateResult) -> float:
    """``result``'s fit score (:attr:`spacemesh.geometry.FitReport.score`, lower is
    better), infinite without a fit report or for a score that is not finite."""
    value = result.fit.score if result.fit is not None else float("nan")
    return value if np.isfinite(value) else float("inf")


def best_fit(tried: list[GenerateResult], options: GenerateOptions,
             expected_pieces: int, *, check: bool = True) -> GenerateResult:
    """The result of the seed that fits best.

    Parameters
    ----------
    tried : list of GenerateResult
        Every seed's result.
    options : GenerateOptions
        The request's resolved options.
    expected_pieces : int
        The points' own piece count.
    check : bool
        Rank a mesh whose pieces agree with ``expected_pieces`` first, then one without
        crossing faces (the model's topology check); else the fit alone.

    Returns
    -------
    GenerateResult
        The winner (lowest rank: the checks, then the fit score, then the lower seed),
        with every seed's score and the request's options at the winner's seed.
    """
    scores = [(r.seed, fit_score_of(r)) for r in tried]

    def rank(i: int) -> tuple[bool, bool, float, int]:
        return (check and not pieces_agree(tried[i], expected_pieces),
                check and crosses(tried[i]), scores[i][1], scores[i][0])

    winner = tried[min(range(len(tried)), key=rank)]
    winner.options = replace(options, seed=winner.seed)
    winner.sample_scores = scores
    return winner


__all__ = ["acceptable", "best_fit", "crosses", "fit_score_of", "pieces_agree"]
