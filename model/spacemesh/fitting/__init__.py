"""Fitting SpaceMesh embeddings by direct optimisation (paper Sec. 4): the torch side.

Needs the training extra (``pip install 'spacemesh[train]'``). The numpy core, the
runtime and the service never import this package.

- :mod:`~spacemesh.fitting.single`: one mesh (Sec. 4.1), :func:`fit_mesh`, behind
  ``spacemesh fit``.

The connectivity scores it reports (edge F1, ``next`` accuracy) are numpy and live in
:mod:`spacemesh.metrics.connectivity`.
"""

from spacemesh.fitting.single import (
    EmbeddingFitConfig,
    EmbeddingFitRecord,
    EmbeddingFitResult,
    fit_mesh,
)

__all__ = ["EmbeddingFitConfig", "EmbeddingFitRecord", "EmbeddingFitResult", "fit_mesh"]
