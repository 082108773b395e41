"""Errors raised by the numpy core for inputs a user can fix."""

from __future__ import annotations


class SpaceMeshError(ValueError):
    """Base class of the user-facing errors of the ``spacemesh`` package."""


class NotManifoldError(SpaceMeshError):
    """The mesh is not a closed, oriented, manifold polygon mesh."""
