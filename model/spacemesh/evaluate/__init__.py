"""Evaluation runs: our model and the baselines on the same inputs, scored and reported.

- :mod:`~spacemesh.evaluate.runner`: shapes from a dataset or a mesh folder,
  :func:`run_evaluation` (tqdm progress) and :func:`write_report`.
- :mod:`~spacemesh.evaluate.gallery`: offscreen matplotlib renders (no GPU needed).

The command line is ``spacemesh eval`` (:mod:`spacemesh.cli.evaluate`).
"""

from spacemesh.evaluate.gallery import GalleryRow, render_gallery
from spacemesh.evaluate.runner import (
    BASELINES,
    EvalResult,
    EvalShape,
    dataset_shapes,
    load_shapes,
    mesh_shapes,
    pin_threads,
    run_evaluation,
    write_report,
)

__all__ = [
    "BASELINES",
    "EvalResult",
    "EvalShape",
    "GalleryRow",
    "dataset_shapes",
    "load_shapes",
    "mesh_shapes",
    "pin_threads",
    "render_gallery",
    "run_evaluation",
    "write_report",
]
