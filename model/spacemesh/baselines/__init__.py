"""Classic baselines, given their inputs as a user would (estimated normals, one thread).

- :mod:`~spacemesh.baselines.normals`: normals estimated and oriented from the points.
- :mod:`~spacemesh.baselines.psr`: screened Poisson (``psr``) and PSR decimated to our
  vertex count (``psr_star``).
- :mod:`~spacemesh.baselines.bpa`: ball pivoting (``bpa``).
- :mod:`~spacemesh.baselines.repair`: MeshFix and trimesh hole filling (repair).

Everything here needs the ``geometry`` extra (pymeshlab, trimesh; pymeshfix for
MeshFix), imported only when a function runs.
"""

from spacemesh.baselines.bpa import ball_pivoting
from spacemesh.baselines.normals import estimate_normals, orient_outward
from spacemesh.baselines.psr import psr_star, screened_poisson
from spacemesh.baselines.repair import fill_holes_trimesh, meshfix

#: Reconstruction baselines by name, in table order.
RECONSTRUCTION_BASELINES = ("psr", "psr_star", "bpa")

__all__ = [
    "RECONSTRUCTION_BASELINES",
    "ball_pivoting",
    "estimate_normals",
    "fill_holes_trimesh",
    "meshfix",
    "orient_outward",
    "psr_star",
    "screened_poisson",
]
