"""Errors raised by the numpy core for inputs a user can fix."""

from __future__ import annotations

from typing import Any


class SpaceMeshError(ValueError):
    """Base class of the user-facing errors of the ``spacemesh`` package."""


class NotManifoldError(SpaceMeshError):
    """The mesh is not a closed, oriented, manifold polygon mesh."""


class KindedError(SpaceMeshError):
    """A user-facing error of a stable ``kind`` (the service's problem type slug).

    Parameters
    ----------
    kind : str
        One of the subclass's :attr:`KINDS`, stable across versions.
    message : str
        One human-readable sentence.
    details : dict, optional
        Machine-readable context (the problem's extension members).
    """

    #: The kinds the subclass may carry.
    KINDS: tuple[str, ...] = ()

    def __init__(self, kind: str, message: str, details: dict[str, Any] | None = None) -> None:
        if kind not in self.KINDS:
            raise ValueError(f"unknown {type(self).__name__} kind {kind!r}")
        super().__init__(message)
        self.kind = kind
        self.details = dict(details or {})
