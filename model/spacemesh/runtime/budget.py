"""A per-request budget of seconds and memory, checked against a request's estimated cost
(:mod:`spacemesh.runtime.cost`) before any work starts.

:meth:`Budget.check` refuses an estimate over the budget with a :class:`CostError` of
kind ``too-expensive`` (the service answers it as that problem type, 422; ``spacemesh
generate --budget-s`` as one line and exit code 2). It names the option to lower: the
one whose default would save the most of what is over (seconds, else memory), and, when
one exists, the largest value of it that fits (``samples=2 fits``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from spacemesh.errors import KindedError
from spacemesh.runtime.cost import Estimate, Lever

#: The kind of a request refused for its estimated cost.
TOO_EXPENSIVE = "too-expensive"
#: Bisection rounds of a suggestion (far more than an integer range of 2**20 needs).
_ROUNDS = 40


class CostError(KindedError):
    """A request whose estimated cost is over the budget: a
    :class:`~spacemesh.errors.KindedError` of kind :data:`TOO_EXPENSIVE`, its ``details``
    ``option`` (the one to lower, or None when no option is above its default),
    ``estimated_seconds``, ``estimated_mb``, ``budget_seconds``, ``budget_mb``,
    ``savings`` (per option, the seconds and MB its default would save) and, when one
    fits, ``suggestion`` (``{option: value}``)."""

    KINDS = (TOO_EXPENSIVE,)

    @property
    def option(self) -> str | None:
        """The option to lower."""
        return self.details.get("option")


@dataclass(frozen=True)
class Budget:
    """What one request may cost.

    Attributes
    ----------
    seconds : float, optional
        Most estimated seconds (None: no limit).
    memory_mb : float, optional
        Most estimated peak memory in MB (None: no limit).
    """

    seconds: float | None = None
    memory_mb: float | None = None

    def fits(self, seconds: float, memory_mb: float) -> bool:
        """Whether a cost of ``seconds`` and ``memory_mb`` is within the budget."""
        return ((self.seconds is None or seconds <= self.seconds)
                and (self.memory_mb is None or memory_mb <= self.memory_mb))

    def describe(self) -> str:
        """``60 s and 2048 MB`` (the limits set)."""
        parts = ([f"{self.seconds:g} s"] if self.seconds is not None else []) + (
            [f"{self.memory_mb:g} MB"] if self.memory_mb is not None else [])
        return " and ".join(parts) or "no limit"

    def check(self, estimate: Estimate, *, what: str = "request") -> None:
        """Refuse ``estimate`` when it is over the budget.

        Parameters
        ----------
        estimate : Estimate
        what : str
            The request's kind, for the message (``generate``, ``repair``).

        Raises
        ------
        CostError
            Over the budget: the message names the option to lower.
        """
        if self.fits(estimate.seconds, estimate.memory_mb):
            return
        over_time = self.seconds is not None and estimate.seconds > self.seconds
        savings = estimate.savings()
        by = 0 if over_time else 1
        ranked = sorted((x for x in estimate.levers if savings[x.name][by] > 0),
                        key=lambda x: -savings[x.name][by])
        details: dict[str, Any] = {
            "option": ranked[0].name if ranked else None,
            "estimated_seconds": round(estimate.seconds, 1),
            "estimated_mb": round(estimate.memory_mb),
            "budget_seconds": self.seconds, "budget_mb": self.memory_mb,
            "savings": {x.name: {"seconds": round(savings[x.name][0], 1),
                                 "mb": round(savings[x.name][1])} for x in ranked},
        }
        message = (f"this {what} is estimated at {estimate.seconds:.0f} s and "
                   f"{estimate.memory_mb:.0f} MB, over the budget of "
                   f"{self.describe()} per request")
        if not ranked:
            raise CostError(TOO_EXPENSIVE, message + ", with every option at its default; "
                            "the budget is too small for this input", details)
        lever = ranked[0]
        value = suggest(estimate, lever, self)
        if value is not None:
            details["suggestion"] = {lever.name: value}
        unit = "s" if over_time else "MB"
        costs = ", ".join(f"{x.name} {_amount(savings[x.name][by])} {unit}" for x in ranked)
        raise CostError(TOO_EXPENSIVE, f"{message}; {_advice(lever, value)}. Each option at "
                        f"its default would save: {costs}", details)


def suggest(estimate: Estimate, lever: Lever, budget: Budget) -> float | None:
    """The value of ``lever`` nearest the request's with which it fits ``budget`` (the
    other inputs unchanged), or None when even its cheapest value does not.

    Bisects between :attr:`Lever.cheapest` and the request's value, assuming the cost
    grows with the value (falls, for :attr:`Lever.raise_to_save`); integers exactly,
    ``start_time`` to 0.01 and ``tolerance`` to two significant digits, rounded toward
    the cheap side.
    """
    def fits(value: float) -> bool:
        return budget.fits(*estimate.with_changes({lever.name: value}))

    good, bad = lever.cheapest, lever.value
    if not fits(good):
        return None
    for _ in range(_ROUNDS):
        middle = (good + bad) / 2
        if lever.integer:
            middle = math.floor(middle) if good < bad else math.ceil(middle)
            if middle in (good, bad):
                break
        if fits(middle):
            good = middle
        else:
            bad = middle
    if lever.integer:
        return int(good)
    rounded = _round_cheap(good, lever.raise_to_save)
    return rounded if fits(rounded) else good


def _amount(value: float) -> str:
    """``4123``, ``12``, ``0.4``: whole numbers from 10 on."""
    return f"{value:.0f}" if value >= 10 else f"{value:.1f}"


def _round_cheap(value: float, up: bool) -> float:
    """``value`` to two significant digits (``up``: rounded up, else to 0.01 down)."""
    if not up:
        return math.floor(value * 100) / 100
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return math.ceil(value / scale) * scale


def _advice(lever: Lever, value: float | None) -> str:
    """What to do about ``lever``: ``lower samples: samples=2 fits``."""
    if lever.name == "points":
        return "send fewer points" + ("" if value is None else f": {value:g} fit")
    if lever.name == "region":
        return "mark a smaller region (fewer passes)"
    if lever.name == "mesh":
        return "send a mesh with fewer faces"
    verb = "raise" if lever.raise_to_save else "lower"
    fit = "" if value is None else f": {lever.name}={value:g} fits"
    return f"{verb} {lever.name}{fit}"


__all__ = ["TOO_EXPENSIVE", "Budget", "CostError", "suggest"]
