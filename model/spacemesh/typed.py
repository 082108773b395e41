"""Shared type aliases, in one place (as ``trimesh.typed`` does)."""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Float array, usually float64 positions or float32 embeddings.
FloatArray: TypeAlias = NDArray[np.floating]
#: Integer index array (int64).
IntArray: TypeAlias = NDArray[np.int64]
#: Boolean mask.
BoolArray: TypeAlias = NDArray[np.bool_]

__all__ = ["ArrayLike", "BoolArray", "FloatArray", "IntArray"]
