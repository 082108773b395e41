"""The SDK's progress callbacks, fed by the events of either transport."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TextIO

#: ``progress(step, total)``: a diffusion step finished.
ProgressFn = Callable[[int, int], None]
#: ``stage(name, done, total)``: a stage of the server's work (or a sampler step).
StageFn = Callable[[str, int, int], None]


@dataclass(frozen=True)
class Reporter:
    """``report(stage, done, total)``: one progress event of a stream, passed on to
    the user's callbacks.

    Parameters
    ----------
    progress : callable or None
        ``progress(step, total)`` for each sampler step (an event of stage ``sampler``
        with ``done`` > 0, or of no stage from a server that reports steps only).
    stage : callable or None
        ``stage(name, done, total)`` for every event with a stage (``queued``,
        ``encoder``, ``sampler``, ``connectivity``, ``decode``, ``geometry``,
        ``report``, ``encode_output``).
    """

    progress: ProgressFn | None = None
    stage: StageFn | None = None

    def __call__(self, name: str, done: int, total: int) -> None:
        if self.stage is not None and name:
            self.stage(name, done, total)
        if self.progress is not None and name in ("sampler", "") and done > 0:
            self.progress(done, total)


def reporter(progress: ProgressFn | None, stage: StageFn | None) -> Reporter | None:
    """A :class:`Reporter` of the callbacks, or None when neither is given."""
    if progress is None and stage is None:
        return None
    return Reporter(progress, stage)


class ProgressBar:
    """A one-line progress bar on a text stream, rewritten in place with ``\\r``:
    ``stage(name, done, total)`` shows the stage and its ``done`` of ``total``.

    Parameters
    ----------
    stream : TextIO
        Where it is drawn (the CLI's stderr).
    width : int
        Characters of the bar itself.
    """

    def __init__(self, stream: TextIO, width: int = 24) -> None:
        self.stream = stream
        self.width = width
        self._last = 0

    def stage(self, name: str, done: int, total: int) -> None:
        """Draw one event (a :data:`StageFn`)."""
        filled = self.width * min(max(done, 0), total) // total if total > 0 else 0
        line = f"{name:<13} [{'#' * filled}{'.' * (self.width - filled)}] {done}/{total}"
        self.stream.write("\r" + line.ljust(self._last))
        self.stream.flush()
        self._last = len(line)

    def close(self) -> None:
        """End the line (once something was drawn)."""
        if self._last:
            self.stream.write("\n")
            self.stream.flush()
            self._last = 0
