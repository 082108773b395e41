"""Mesh repair by diffusion inpainting (paper Sec. 5.5 and Supplement D).

- :mod:`~spacemesh.repair.region`: the region a user marks (:class:`Region`,
  :func:`parse_region`) and :class:`RegionError` with its stable ``kind``.
- :mod:`~spacemesh.repair.weld`: merging vertices split at seams (``weld=True``), and
  mapping a region onto the welded mesh.
- :mod:`~spacemesh.repair.auto`: automatic regions (``{"auto": "holes"}``...): holes and
  defects found (:mod:`~spacemesh.repair.findings`), the faces oriented
  (:mod:`~spacemesh.repair.orient`), defects unzipped (:mod:`~spacemesh.repair.unzip`),
  pinched loops split (:mod:`~spacemesh.repair.pinched`), each region repaired by a pass
  of its own.
- :mod:`~spacemesh.repair.fill`: hole filling once the passes are done: the fairing,
  the fan, flat and MeshFix fills, the probe holes that choose among them, and the
  :class:`~spacemesh.repair.fill.policy.FillPolicy` that says how.
- :mod:`~spacemesh.repair.halfedges`: the halfedge tables of a set of faces.
- :mod:`~spacemesh.repair.cut`: cutting the region out, growth, boundary loops, and
  the defects left outside.
- :mod:`~spacemesh.repair.patch`: the local patch the model sees, and its point sets.
- :mod:`~spacemesh.repair.inpaint`: the inpainting sampler over the runtime backend.
- :mod:`~spacemesh.repair.splice`: new faces from the predicted connectivity, spliced
  into the boundary fans.
- :mod:`~spacemesh.repair.crossings`: whether new faces cross the mesh, and their
  mending; :mod:`~spacemesh.repair.regrow`: a region still crossing grown around the
  crossings and repaired again.
- :mod:`~spacemesh.repair.result`: :class:`RepairResult` and :class:`RepairStats`.
- :mod:`~spacemesh.repair.api`: :func:`repair_mesh` and :func:`plan_repair`.

numpy, scipy and onnxruntime only (never torch). See docs/REPAIR.md.
"""

from spacemesh.repair.api import (
    DEFAULT_MAX_GROWTH,
    RepairPlan,
    RepairResult,
    RepairStats,
    plan_repair,
    repair_mesh,
    verify_repair,
)
from spacemesh.repair.auto import AutoPlan
from spacemesh.repair.fill.kinds import Fairing, FilledBy, FillKind
from spacemesh.repair.fill.policy import FillPolicy
from spacemesh.repair.region import ERROR_KINDS, Region, RegionError, parse_region
from spacemesh.repair.weld import weld_vertices

__all__ = [
    "DEFAULT_MAX_GROWTH",
    "ERROR_KINDS",
    "AutoPlan",
    "Fairing",
    "FillKind",
    "FillPolicy",
    "FilledBy",
    "Region",
    "RegionError",
    "RepairPlan",
    "RepairResult",
    "RepairStats",
    "parse_region",
    "plan_repair",
    "repair_mesh",
    "verify_repair",
    "weld_vertices",
]
