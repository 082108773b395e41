"""Equal positions merged: the one weld behind the STL reader, repair's weld and the
topology a user sees."""

from __future__ import annotations

import numpy as np

from spacemesh.typed import FloatArray, IntArray


def weld(corners: FloatArray) -> tuple[FloatArray, IntArray]:
    """Merge exactly equal rows, like ``np.unique(corners, axis=0, return_inverse=True)``.

    Parameters
    ----------
    corners : (C, 3) float64
        Positions; ``-0.0`` and ``0.0`` count as equal.

    Returns
    -------
    vertices : (V, 3) float64
        The distinct rows in lexicographic order.
    inverse : (C,) int64
        ``vertices[inverse] == corners``.
    """
    order = np.lexsort((corners[:, 2], corners[:, 1], corners[:, 0]))
    ordered = corners[order]
    new = np.ones(len(ordered), dtype=bool)
    new[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    inverse = np.empty(len(corners), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return ordered[new], inverse
