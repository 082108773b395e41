"""Cooperative cancellation inside long stages: :func:`checkpoint` raises
:class:`Cancelled` when the work running in this thread is no longer wanted.

The service's batcher runs a batch in its inference thread inside :func:`cancel_scope`,
whose check says whether anyone still waits for the batch (a deadline passed, a client
went away, a gRPC call was cancelled). Long loops call :func:`checkpoint` on every
round (the vertex fit's iterations, the geometry stage's rounds and guard, edge
collapses, untangling; a repair's samplings, sampler steps, splice rounds, passes and the
fills' fairings, refinement rounds and probes; an automatic region's planning), so
abandoned work stops within one round instead of at the next stage. Outside a scope
(the CLI, batch, tests) :func:`checkpoint` does nothing.
The scope is per thread, so concurrent work in other threads is not affected.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

_local = threading.local()


class Cancelled(Exception):
    """The work of this thread's :func:`cancel_scope` is no longer wanted."""


@contextmanager
def cancel_scope(is_cancelled: Callable[[], bool]) -> Iterator[None]:
    """Run the body with ``is_cancelled`` as this thread's cancellation check.

    Parameters
    ----------
    is_cancelled : callable
        ``is_cancelled() -> bool``, cheap (it is called on every round of long loops).
    """
    outer = getattr(_local, "check", None)
    _local.check = is_cancelled
    try:
        yield
    finally:
        _local.check = outer


def cancelled() -> bool:
    """Whether this thread's scope says the work is not wanted (False outside a scope).

    Returns
    -------
    bool
    """
    check = getattr(_local, "check", None)
    return bool(check is not None and check())


def checkpoint() -> None:
    """Raise :class:`Cancelled` if this thread's scope says the work is not wanted.

    Raises
    ------
    Cancelled
        Inside a :func:`cancel_scope` whose check returns True.
    """
    if cancelled():
        raise Cancelled


__all__ = ["Cancelled", "cancel_scope", "cancelled", "checkpoint"]
