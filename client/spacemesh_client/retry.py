"""When to send a request again, and how long to wait first.

Retried: errors whose class is ``retryable`` — :class:`~spacemesh_client.errors.Unavailable`
(503 ``queue-full``, ``not-ready``, ``shutting-down``, and 429 from a proxy) and
:class:`~spacemesh_client.errors.ConnectionFailed` (nothing reached the server, or the
connection dropped). These are safe to repeat: a 503 or 429 means the server did not take
the request, and generating a mesh changes nothing on the server.

The wait is exponential backoff with full jitter (``uniform(0, min(cap, base * 2**n))``),
but never less than the server's ``Retry-After``; a ``Retry-After`` beyond
``max_retry_after`` gives up at once rather than sleeping that long.
"""

from __future__ import annotations

import logging
import random
from dataclasses import dataclass, field

from spacemesh_client.errors import SpaceMeshError

log = logging.getLogger("spacemesh_client")


@dataclass(frozen=True)
class RetryPolicy:
    """How often and how patiently a client repeats a request.

    Parameters
    ----------
    attempts : int
        Tries in all (1: never retry).
    backoff : float
        Base of the exponential backoff, in seconds.
    max_backoff : float
        Cap of one backoff wait, in seconds.
    max_retry_after : float
        The longest ``Retry-After`` honoured; a longer one raises at once.
    jitter : bool
        Full jitter (spreads clients that failed together); off: ``base * 2**n``.
    """

    attempts: int = 5
    backoff: float = 0.25
    max_backoff: float = 8.0
    max_retry_after: float = 60.0
    jitter: bool = True
    _random: random.Random = field(default_factory=random.Random, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.attempts < 1:
            raise ValueError(f"attempts must be at least 1, not {self.attempts}")
        if self.backoff < 0 or self.max_backoff < 0 or self.max_retry_after < 0:
            raise ValueError("backoff, max_backoff and max_retry_after must be >= 0")

    @classmethod
    def never(cls) -> RetryPolicy:
        """One attempt only."""
        return cls(attempts=1)

    def delay(self, attempt: int, error: SpaceMeshError) -> float | None:
        """Seconds to wait before the next attempt, or None to give up.

        Parameters
        ----------
        attempt : int
            The attempt that just failed (1 for the first).
        error : SpaceMeshError
            How it failed.

        Returns
        -------
        float or None
        """
        if not error.retryable or attempt >= self.attempts:
            return None
        ceiling = min(self.max_backoff, self.backoff * 2 ** (attempt - 1))
        wait = self._random.uniform(0, ceiling) if self.jitter else ceiling
        if error.retry_after is not None:
            if error.retry_after > self.max_retry_after:
                return None
            wait = max(wait, error.retry_after)
        log.info("attempt %d failed (%s); retrying in %.2f s", attempt,
                 type(error).__name__, wait)
        return wait


#: What clients use unless told otherwise.
DEFAULT_RETRY = RetryPolicy()
