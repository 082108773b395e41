"""Hole filling: the fills an automatic region of holes can end with once the model's
passes are done, and the policy that chooses among them (docs/REPAIR.md, step 5).

- :mod:`~spacemesh.repair.fill.policy`: :class:`FillPolicy`, passed explicitly;
- :mod:`~spacemesh.repair.fill.kinds`: the names of fills and outcomes (string enums);
- :mod:`~spacemesh.repair.fill.finish`: a region's patch faired, laid onto another fill
  or replaced, as the policy says;
- :mod:`~spacemesh.repair.fill.replace`: a region's patch replaced by another fill;
- :mod:`~spacemesh.repair.fill.probe`: probe holes punched nearby choose the fill;
- :mod:`~spacemesh.repair.fill.fairing`: a patch refined and faired into the surface,
  with :mod:`~spacemesh.repair.fill.refine`, :mod:`~spacemesh.repair.fill.laplace`,
  :mod:`~spacemesh.repair.fill.planar` and :mod:`~spacemesh.repair.fill.flat`;
- :mod:`~spacemesh.repair.fill.fan`, :mod:`~spacemesh.repair.fill.flat`,
  :mod:`~spacemesh.repair.fill.meshfix`: the fan, the least-area flat fill and
  MeshFix's fill;
- :mod:`~spacemesh.repair.fill.lay`: a patch laid onto another fill's surface;
- :mod:`~spacemesh.repair.fill.loops`: a patch's loops, parts, density and Euler
  characteristic;
- :mod:`~spacemesh.repair.fill.passes`: the mesh between the passes.
"""

from spacemesh.repair.fill.kinds import Fairing, FilledBy, FillKind
from spacemesh.repair.fill.policy import DEFAULT_POLICY, FillPolicy

__all__ = ["DEFAULT_POLICY", "Fairing", "FillKind", "FillPolicy", "FilledBy"]
